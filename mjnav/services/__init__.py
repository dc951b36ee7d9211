"""mjnav.services."""
