#!/usr/bin/env bash
# Check that a `pasta run` log converts to Rerun's format and verifies clean (docs/logging.md).
# Needs the Rerun CLI (`pip install rerun-sdk`, tested with 0.41.0), in this environment or given as RERUN=.
# Usage: scripts/check_rerun.sh [RUN.mcap]   (without a file: makes one with a short crs run)
set -euo pipefail
RERUN=${RERUN:-rerun}
PY=${PY:-.venv/bin/python}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
log=${1:-}
if [[ -z "$log" ]]; then
    log="$work/run.mcap"
    "$PY" -m pasta run task=crs seed=1000 planner.iterations=10 execute.idle_steps=2 log="$log" > /dev/null
fi
"$RERUN" mcap check "$log"
"$RERUN" mcap convert "$log" -o "$work/run.rrd" > /dev/null 2>&1
"$RERUN" rrd verify "$work/run.rrd"
echo "rerun: $log converts and verifies without error"
