"""``cellrunner schema [cell|task] [--write DIR]``: JSON Schema for editors."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from cellrunner.model.schema import cell_schema, task_schema


def run(args: argparse.Namespace) -> int:
    schemas = {"cell": cell_schema(), "task": task_schema()}
    if args.write:
        folder = Path(args.write)
        folder.mkdir(parents=True, exist_ok=True)
        for kind, schema in schemas.items():
            (folder / f"{kind}.schema.json").write_text(json.dumps(schema, indent=2) + "\n")
        sys.stderr.write(f"wrote {folder}/cell.schema.json and {folder}/task.schema.json\n")
        return 0
    out = schemas[args.kind] if args.kind else schemas
    sys.stdout.write(json.dumps(out, indent=2) + "\n")
    return 0
