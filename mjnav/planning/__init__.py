"""mjnav.planning."""
