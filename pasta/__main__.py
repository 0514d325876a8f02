import sys

from pasta.cli import main

sys.exit(main())
