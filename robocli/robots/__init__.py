"""Robot models apart from their wire formats: parameters and geometry (no sockets, no bytes)."""
