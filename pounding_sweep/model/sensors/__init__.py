"""Raw sensor exports -> the engine's experiment table and record (docs/how-to/import-real-sensor-data.md): formats (the registry
of readers), signals (lag and sign of one record against another where the floors follow the table),
assemble (the import's steps), checks (what a table's channels say about a sensor's sign, lag, offset)."""
