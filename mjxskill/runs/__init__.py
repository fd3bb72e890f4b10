"""A run directory and its files: layout, the lock, the settings and config it records, the
evaluations CSV, atomic writes and resume. Nothing here parses arguments or exits."""
