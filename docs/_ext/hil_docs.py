"""Pages of the documentation site generated from the code when Sphinx starts, so none is kept by hand: the
requirement matrix (``hil spec``'s, from the catalogue and the suites' ``spec()`` markers), the command-line
reference (from the argparse parsers, :mod:`hil.cli.reference`), the bench profile's keys (from their
declarations, :mod:`hil.bench.schema_export`), the architecture's diagram (from the import-linter contracts,
layers_svg.py) and the measured figures (the JSON the benchmark scripts write into docs/figures/)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from layers_svg import layers_svg

from hil.bench.schema_export import markdown as profile_keys
from hil.cli.main import build_parser
from hil.cli.reference import render as command_reference
from hil.cli.spec import build
from hil.core.paths import suites_dir

DOCS = Path(__file__).resolve().parent.parent
GENERATED = DOCS / "_generated"


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def requirement_matrix() -> str:
    """The matrix as a Markdown page: per statement its source, the tests that name it, or why none does."""
    code, matrix, output = build(suites_dir())
    if code not in (0, 5):
        raise RuntimeError(f"collecting the suites for the requirement matrix failed (pytest exit {code}):\n{output}")
    rows = []
    for req in matrix.requirements.values():
        tests = matrix.tests.get(req.id, [])
        if tests:
            checked = "<br>".join(f"`{_cell(t)}`" for t in tests)
        else:
            checked = f"no test — {req.untested_kind}: {_cell(req.untested_reason)}" if req.untested else "MISSING"
        choice = " *[our choice]*" if req.choice else ""
        rows.append(f"| `{req.id}` | {_cell(req.manual)} | {_cell(req.statement)}{choice} | {checked} |")
    tested = sum(1 for r in matrix.requirements.values() if matrix.tests.get(r.id))
    return "\n".join([
        "# Requirement matrix", "",
        "Generated from `hil/requirements.toml` and the suites' `spec()` markers when this site was built — the "
        "same matrix `hil spec -v` prints.", "",
        f"{len(matrix.requirements)} statements, {tested} checked by at least one test.", "",
        "| requirement | manual | statement | checked by |", "|---|---|---|---|", *rows, ""])


FIGURES = DOCS / "figures"


def bench_time_tables() -> str:
    """The bench-time runs benchmarks/bench_time.py --record wrote (docs/figures/bench-time-*.json), a table each:
    per suite file the tests' own time, the bytes on the wire and the round trips; the session's wall time."""
    out = ["# Measured bench time", "",
           "Written by `python benchmarks/bench_time.py … --record NAME` (docs/figures/bench-time-NAME.json) and "
           "shown here as measured: no figure on this page is typed by hand.", ""]
    for path in sorted(FIGURES.glob("bench-time-*.json")):
        run = json.loads(path.read_text(encoding="utf-8"))
        lanes = f", `--lanes {run['lanes']}`" if run.get("lanes", 1) > 1 else ""
        seed = f", seed {run['seed']}" if run.get("seed") is not None else ""
        total = run["total_wall_s"]
        chars = any("characters_s" in row for row in run["per_suite"].values())  # a paced line's
        out += [f"## {run['wire']}{lanes}, {run['timing']} timing{seed}, time scale {run['time_scale']:g}", "",
                f"**{total:.0f} s** session wall time ({'within' if total <= 180 else 'over'} the 180 s target); "
                f"measured {run['measured']} at commit `{run['commit']}` on a {run['cpus']}-core host.", "",
                "| suite | tests | failed | skipped | tests' time | on the wire | round trips |"
                + (" characters alone |" if chars else ""),
                "|---|---|---|---|---|---|---|" + ("---|" if chars else "")]
        for name, row in run["per_suite"].items():
            cells = [f"`{name}`", row["tests"], row["failures"], row["skipped"], f"{row['test_time_s']:.1f} s",
                     f"{row['wire_bytes'] / 1000:.1f} KB", row["requests"]]
            if "characters_s" in row:
                cells.append(f"{row['characters_s']:.1f} s")
            out.append("| " + " | ".join(map(str, cells)) + " |")
        out.append("")
    return "\n".join(out)


def mutation_scores() -> str:
    """The mutation scores ``benchmarks/mutation.py --record`` wrote (docs/figures/mutation-*.json): per run its
    sample, the mutants killed and the survivors by kind, the score and the score of what a bench could show."""
    out = ["| run | mutants run (of all) | killed | survivors: equivalent · [our choice] · not observable · gap | "
           "score | of what a bench could show | measured |", "|---|---|---|---|---|---|---|"]
    for path in sorted(FIGURES.glob("mutation-*.json")):
        run = json.loads(path.read_text(encoding="utf-8"))
        kinds = run["survivors_by_kind"]
        gaps = kinds.get("gap", 0) + kinds.get("unclassified", 0)
        which = "every mutant" if run["sample"] is None else f"`--sample {run['sample']}`, seed {run['seed']}"
        out.append(f"| {which} | {run['run']} ({sum(run['mutants_total'].values())}) | {run['killed']} | "
                   f"{kinds.get('equivalent', 0)} · {kinds.get('choice', 0)} · {kinds.get('not_observable', 0)} · "
                   f"{gaps} | **{run['score_percent']} %** | {run['score_observable_percent']} % | "
                   f"{run['measured']}, commit `{run['commit']}` |")
    return "\n".join([*out, ""])


def device_operations_table() -> str:
    """The FATEK bytes per device operation ``benchmarks/run.py --record`` measured (docs/figures/
    device-operations.json): per procedure its round trips and bytes against the fewest the frame format allows, on a
    direct line and with every read fenced."""
    run = json.loads((FIGURES / "device-operations.json").read_text(encoding="utf-8"))
    rows = [f"| `{op['operation']}` | {op['round_trips']} | {op['bytes']} ({op['min_bytes']}) | {op['ratio']:.2f}× | "
            f"{op['fenced_ratio']:.2f}× |" for op in run["operations"]]
    return "\n".join([
        f"Measured {run['measured']} at commit `{run['commit']}` on the in-process emulator: `{run['direct']}` for a "
        f"direct line, `{run['fenced']}` for a line that may repeat replies.", "",
        "| operation | round trips | bytes (fewest) | direct line | `fence=reads` |", "|---|---|---|---|---|",
        *rows, ""])


def _write(name: str, text: str) -> None:
    GENERATED.mkdir(exist_ok=True)
    target = GENERATED / name
    if not target.is_file() or target.read_text(encoding="utf-8") != text:  # (an unchanged file: no rebuild)
        target.write_text(text, encoding="utf-8")


def _generate(app: Any) -> None:
    _write("requirements.md", requirement_matrix())
    _write("bench-time.md", bench_time_tables())
    _write("device-operations.md", device_operations_table())
    _write("mutation.md", mutation_scores())
    _write("commands.md", command_reference(build_parser()))
    _write("profile-keys.md", profile_keys())
    _write("layers.svg", layers_svg(DOCS.parent / "pyproject.toml", DOCS.parent))


def setup(app: Any) -> dict[str, Any]:
    app.connect("builder-inited", _generate)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
