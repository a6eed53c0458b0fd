"""HDF5 run files: one self-describing file per run, written by SWMR, read while written.

The rooms of the store, one job each (the layout is described in docs/run-format.md):

- `schema`: the file layout, one table of datasets (paths, shapes, types, storage, units).
- `files`: file safety (whole files only, the writer lock, opening missing/foreign/corrupt files).
- `reader`: `RunReader`, also while a writer is flushing.
- `writer`: `RunWriter` (training, resume) and `add_implementation`.
- `legacy`: task run files of the old format ("gnp-lab-task-run"), read, and resumed into this.
- `catalogue`: run names and the runs folder.
"""

from app.store.catalogue import (
    BEST_OF_RUN,
    LAST_BEST,
    RunSummary,
    best_words,
    list_runs,
    new_run_path,
    resolve_run,
    run_files,
    run_name,
    summarize,
)
from app.store.files import RunFileError
from app.store.reader import History, Implementation, RunReader, file_kind
from app.store.schema import (
    FORMAT,
    RUN_KINDS,
    SCHEMA_VERSION,
    TASK,
    RunKind,
    RunTemplate,
    package_version,
)
from app.store.writer import RunWriter, add_implementation

__all__ = [
    "BEST_OF_RUN",
    "FORMAT",
    "LAST_BEST",
    "RUN_KINDS",
    "SCHEMA_VERSION",
    "TASK",
    "History",
    "Implementation",
    "RunFileError",
    "RunKind",
    "RunReader",
    "RunSummary",
    "RunTemplate",
    "RunWriter",
    "add_implementation",
    "best_words",
    "file_kind",
    "list_runs",
    "new_run_path",
    "package_version",
    "resolve_run",
    "run_files",
    "run_name",
    "summarize",
]
