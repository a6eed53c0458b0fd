"""Settings: the frozen run configuration, its fields, presets, arenas and CLI options."""
