"""mjnav.smoothing."""
