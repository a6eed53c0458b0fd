"""`gnp-lab`: train, implement, list and inspect runs, serve the dashboard; one module per command
(`train`, `implement`, `runs`, `serve`; `experiment`, `export` and `replay` live with their
packages), the parser in `parser`, the entry point in `main`.

A user mistake ends with one line on stderr (`gnp-lab: error: ...`) and a non-zero exit status;
no command overwrites or damages an existing run file.
"""

from app.cli.main import main

__all__ = ["main"]
