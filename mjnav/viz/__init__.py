"""mjnav.viz."""
