"""Write or check the shipped JSON Schema of the run record.

    python scripts/maintainer/record_schema.py [--write | --check]

The record is defined in ``hnnbench/_record/fields.py``; the JSON Schema
``hnnbench/resources/record.schema.json`` is made from that definition. With no option
the schema is printed; ``--write`` rewrites the file (after changing the definition);
``--check`` exits 1 when the file differs from the definition (tests/unit/test_records_schema.py
checks the same).
"""

from __future__ import annotations

import sys

from hnnbench._record.fields import SCHEMA_FILE, schema_text


def main(argv: list[str]) -> int:
    text = schema_text()
    if argv == ["--write"]:
        SCHEMA_FILE.write_text(text, encoding="utf-8")
        print(f"wrote {SCHEMA_FILE}")
    elif argv == ["--check"]:
        if SCHEMA_FILE.read_text(encoding="utf-8") != text:
            print(
                f"{SCHEMA_FILE} differs from hnnbench/_record/fields.py: run "
                "python scripts/maintainer/record_schema.py --write",
                file=sys.stderr,
            )
            return 1
    elif not argv:
        sys.stdout.write(text)
    else:
        print(__doc__.strip().splitlines()[2].strip(), file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
