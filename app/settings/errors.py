"""The settings' one error: a configuration value, file, preset or family that is invalid."""


class ConfigError(ValueError):
    """A configuration value, file or preset is invalid; the message names the problem."""
