"""gnp package."""
