"""mjnav.sim."""
