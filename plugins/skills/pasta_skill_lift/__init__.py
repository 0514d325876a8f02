"""The built-in lift skill: the spatula lifts one dough piece onto the raised cutting board."""
