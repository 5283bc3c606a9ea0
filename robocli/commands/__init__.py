"""CLI commands: thin Typer functions over the library (imports inside the functions)."""
