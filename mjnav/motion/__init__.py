"""mjnav.motion."""
