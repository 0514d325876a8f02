"""Built-in skill plugin 'roll': roll one dough piece flat with the roller."""
