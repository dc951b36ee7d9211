"""mjnav.control."""
