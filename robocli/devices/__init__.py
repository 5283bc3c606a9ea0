"""Clients of real robots: each owns a reader thread, keep-alive, state and typed methods."""
