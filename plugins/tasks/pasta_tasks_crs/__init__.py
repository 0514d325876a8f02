"""The built-in tasks of the CRS family: single-skill cut / push / roll, cut_rearrange, crs, crs_twice and
crs_distractors."""
