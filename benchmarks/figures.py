"""Figures for the documentation site: a benchmark's result, stamped with when, where and at which commit it was
measured, written as docs/figures/NAME.json, which docs/_ext/hil_docs.py renders into the site when it builds —
so no measured figure on a page is ever typed by hand."""

from __future__ import annotations

import datetime as dt
import json
import os
import subprocess
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
FIGURES = ROOT / "docs" / "figures"


def record(result: dict[str, Any], name: str) -> Path:
    """``result`` and its stamp (``measured``, ``commit``, ``cpus``) as docs/figures/NAME.json."""
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True)
    stamped = {**result, "measured": dt.datetime.now(dt.UTC).strftime("%Y-%m-%d %H:%M UTC"),
               "commit": commit.stdout.strip() or "unknown", "cpus": os.cpu_count()}
    target = FIGURES / f"{name}.json"
    target.parent.mkdir(exist_ok=True)
    target.write_text(json.dumps(stamped, indent=1, sort_keys=True) + "\n", encoding="utf-8")
    return target
