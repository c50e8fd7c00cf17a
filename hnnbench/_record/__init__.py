"""The record: one ``result.json`` per job and seed, the boundary between running and
results. A job writes its records through it; every table, report, check and publication
reads them back through its one loader (docs/ARCHITECTURE.md, "The result record").

Its API, re-exported here, is what the rest of hnnbench uses: ``from hnnbench import
_record as records``. The modules: :mod:`~hnnbench._record.fields` (the record defined
once), :mod:`~hnnbench._record.tracks` (track and tuning), :mod:`~hnnbench._record.
validation` (what a record is held to), :mod:`~hnnbench._record.codec` (strict JSON),
:mod:`~hnnbench._record.store` (files written atomically, read bounded),
:mod:`~hnnbench._record.loader` (the loader), :mod:`~hnnbench._record.environment` (its
provenance).
"""

from hnnbench._record.codec import (
    MAX_DEPTH,
    decode,
    encode,
)
from hnnbench._record.environment import (
    environment,
    git_commit,
    now_iso,
)
from hnnbench._record.fields import (
    FIELDS,
    FINISHED,
    OPTIONAL,
    PROVENANCE_FIELDS,
    RECORD_NAME,
    REQUIRED,
    ROLLOUT_NAME,
    SCHEMA_FILE,
    SCHEMA_VERSION,
    SCHEMA_VERSIONS,
    VALUE,
    VERSION_FIELDS,
    WRITTEN,
    Field,
    json_schema,
    new_record,
    schema_text,
)
from hnnbench._record.loader import (
    Loaded,
    Unreadable,
    load,
    load_records,
    scan_records,
)
from hnnbench._record.store import (
    MAX_RECORD_BYTES,
    MAX_ROLLOUT_BYTES,
    InvalidRecord,
    UnsafeFile,
    atomic_path,
    atomic_write_text,
    load_arrays,
    open_regular,
    read_record,
    write_record,
)
from hnnbench._record.tracks import (
    SELECTED_ON,
    STEPS_SETTING,
    TRACK_KEYS,
    track_of,
    track_problem,
    tuned_settings,
)
from hnnbench._record.validation import (
    FUTURE_SKEW,
    STRICT_CHECKS,
    VARIANT_TOKEN_PATTERN,
    created_at_problem,
    created_at_problems,
    history_problems,
    is_date_time,
    metric_domain_problems,
    schema,
    shape_problems,
    strict_problems,
    validate,
    variant_problem,
)

__all__ = [
    "FIELDS",
    "FINISHED",
    "FUTURE_SKEW",
    "Field",
    "InvalidRecord",
    "Loaded",
    "MAX_DEPTH",
    "MAX_RECORD_BYTES",
    "MAX_ROLLOUT_BYTES",
    "OPTIONAL",
    "PROVENANCE_FIELDS",
    "RECORD_NAME",
    "REQUIRED",
    "ROLLOUT_NAME",
    "SCHEMA_FILE",
    "SCHEMA_VERSION",
    "SCHEMA_VERSIONS",
    "SELECTED_ON",
    "STEPS_SETTING",
    "STRICT_CHECKS",
    "TRACK_KEYS",
    "Unreadable",
    "UnsafeFile",
    "VALUE",
    "VARIANT_TOKEN_PATTERN",
    "VERSION_FIELDS",
    "WRITTEN",
    "atomic_path",
    "atomic_write_text",
    "created_at_problem",
    "created_at_problems",
    "decode",
    "encode",
    "environment",
    "git_commit",
    "history_problems",
    "is_date_time",
    "json_schema",
    "load",
    "load_arrays",
    "load_records",
    "metric_domain_problems",
    "new_record",
    "now_iso",
    "open_regular",
    "read_record",
    "scan_records",
    "schema",
    "schema_text",
    "shape_problems",
    "strict_problems",
    "track_of",
    "track_problem",
    "tuned_settings",
    "validate",
    "variant_problem",
    "write_record",
]
