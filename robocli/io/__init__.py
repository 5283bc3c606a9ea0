"""Recorders and readers of captures and logs, chosen by file suffix."""
