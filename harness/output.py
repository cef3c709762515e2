"""Output files that are never left half-written.

The implementation lives in :mod:`monorarp.io` (the pipeline's ``monorarp video``
command needs it too, and :mod:`monorarp` never imports the harness); this
module re-exports it under its historical name.
"""

from monorarp.io import (  # noqa: F401  (re-exports)
    JsonlWriter,
    OutputError,
    atomic_output_dir,
    dumps,
    to_jsonable,
    write_json_atomic,
)

__all__ = ["JsonlWriter", "OutputError", "atomic_output_dir", "dumps", "to_jsonable", "write_json_atomic"]
