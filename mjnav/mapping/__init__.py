"""mjnav.mapping."""
