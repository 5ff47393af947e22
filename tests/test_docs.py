"""The documentation site: it builds with warnings as errors, its front page fits a phone's width, its
command-line reference leaves no option unexplained, and the commands its getting-started and bench-profile pages
show run as written (against the emulator; the documentation's example PLC address is served by ``hil emulate``)."""

from __future__ import annotations

import argparse
import importlib.util
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from hil.cli.main import build_parser
from hil.cli.reference import render, undocumented
from tests import processes
from tests.browser import look, needs_chromium
from tests.external import emulate_process

REPO = Path(__file__).resolve().parent.parent
DOCS = REPO / "docs"
#: the pages whose commands a newcomer types first: each `$ hil …` line of their ```console blocks runs in CI
RUN_PAGES = ("getting-started.md", "profiles.md")
#: the PLC the documentation talks to; the test serves an emulator there (FATEK/TCP on loopback)
DOC_PLC = "fatek+tcp://192.168.1.5:500"
SPHINX = all(importlib.util.find_spec(m) for m in ("sphinx", "myst_parser", "furo"))


def documented_commands(text: str) -> list[str]:
    """The ``$ hil …`` lines of a Markdown page's ```console blocks, in order (indented blocks included)."""
    commands = []
    for block in re.findall(r"(?ms)^[ \t]*```console\n(.*?)^[ \t]*```", text):
        commands += [line.strip()[2:] for line in block.splitlines() if line.strip().startswith("$ hil ")]
    return commands


def run_documented(commands: list[str], cwd: Path, plc: str) -> list[str]:
    """Run each command as a user would (``hil`` from this environment, in ``cwd``), the documentation's PLC
    replaced by ``plc``; what failed, with its exit code and the end of its output."""
    failed = []
    for command in commands:
        args = shlex.split(command.replace(DOC_PLC, plc))
        done = processes.run([sys.executable, "-m", "hil.cli.main", *args[1:]], timeout=300, cwd=cwd)
        if done.returncode != 0:
            failed.append(f"`{command}` exited {done.returncode}: {(done.stdout + done.stderr)[-600:]}")
    return failed


needs_sphinx = pytest.mark.skipif(not SPHINX, reason="Sphinx, MyST-Parser or furo is not installed "
                                                    "(pip install -e '.[test]')")


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The site built once for this module's tests, warnings as errors: its HTML directory."""
    out = tmp_path_factory.mktemp("docs")
    done = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-E", "-q", "-b", "html",
                           "-d", str(out / "doctrees"), str(DOCS), str(out / "html")],
                          capture_output=True, text=True, timeout=300, cwd=REPO)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-3000:]
    return out / "html"


@needs_sphinx
def test_the_site_builds_with_warnings_as_errors(site: Path) -> None:
    page = (site / "_generated" / "commands.html").read_text(encoding="utf-8")
    assert "hil history trend" in page
    matrix = (site / "_generated" / "requirements.html").read_text(encoding="utf-8")
    assert "RTC-VAL-1" in matrix and "PID-LAW-2" in matrix
    performance = (site / "performance.html").read_text(encoding="utf-8")  # docs/figures/device-operations.json
    assert "rtc.adjust_30s()" in performance and "fence=reads" in performance


def test_no_measured_figure_is_typed_into_a_page() -> None:
    """A table of measured ratios comes from docs/figures/ (a benchmark's --record) through docs/_ext/hil_docs.py,
    never by hand: a hand-kept one went stale with every re-measure."""
    measured = re.compile(r"^\|.*\d\.\d\d×")
    typed = [f"docs/{page.name}:{n}: {line}" for page in sorted(DOCS.glob("*.md"))
             for n, line in enumerate(page.read_text(encoding="utf-8").splitlines(), 1) if measured.match(line)]
    assert not typed, "\n".join(typed)


@needs_sphinx
@needs_chromium
@pytest.mark.parametrize("page", ["index.html", "architecture.html"])  # the front page; the one with a diagram
def test_the_page_fits_a_phone_a_tablet_and_a_laptop(site: Path, page: str) -> None:
    for width, layout in look(site / page).items():
        assert layout.fits, f"at {width} px {page} is {layout.scroll_width} px wide: {layout.offenders}"


def test_the_architecture_diagram_is_drawn_from_the_import_contracts(tmp_path: Path) -> None:
    """Every layer of pyproject's contracts is in the picture, captioned by its docstring; a layer added to the
    contract is drawn without anyone touching the page."""
    spec = importlib.util.spec_from_file_location("layers_svg", DOCS / "_ext" / "layers_svg.py")
    assert spec and spec.loader
    module = sys.modules["layers_svg"] = importlib.util.module_from_spec(spec)  # (its dataclass looks itself up)
    spec.loader.exec_module(module)  # the site's extension module, as docs/conf.py loads it (not a package)
    layers_svg = module.layers_svg
    svg = layers_svg(REPO / "pyproject.toml", REPO)
    layers = ("hil.cli", "hil.history", "hil.plugin", "hil.families", "hil.bench", "hil.sim", "hil.io", "hil.core")
    for name in (*layers, "fbs/", "s7smart/", "device", "transport", "protocol", "≠ independent: fbs, s7smart"):
        assert f">{name}" in svg, name
    assert ">One module per hil subcommand<" in svg  # hil/cli/__init__.py's first sentence
    assert "No import cycles between the packages" in svg  # a contract drawn as a sentence
    changed = tmp_path / "pyproject.toml"
    changed.write_text((REPO / "pyproject.toml").read_text(encoding="utf-8").replace(
        '"hil.bench", "hil.sim"', '"hil.bench", "hil.api", "hil.sim"', 1), encoding="utf-8")
    assert ">hil.api<" in layers_svg(changed, REPO) and ">hil.api<" not in svg


def test_every_command_and_option_has_a_description() -> None:
    assert undocumented(build_parser()) == []
    page = render(build_parser())
    for command in ("`hil run`", "`hil history export`", "`hil drift measure`", "`hil emulate`"):
        assert command in page


def test_an_option_without_a_description_is_named() -> None:
    parser = argparse.ArgumentParser(prog="hil")
    sub = parser.add_subparsers()
    run = sub.add_parser("run", help="run the suites")
    run.add_argument("--quiet-ish")
    sub.add_parser("mute")
    assert undocumented(parser) == ["hil: (the command itself)", "hil run: --quiet-ish",
                                    "hil mute: (the command itself)"]


def test_the_pages_commands_are_collected_from_their_console_blocks() -> None:
    text = "x\n```console\n$ hil list\nsome output\n$ ls\n```\n\n   ```console\n   $ hil probe URL\n   ```\n"
    assert documented_commands(text) == ["hil list", "hil probe URL"]
    for page in RUN_PAGES:
        assert documented_commands((DOCS / page).read_text()), f"docs/{page} shows no `$ hil …` command"


@pytest.mark.e2e
def test_the_documented_commands_run_as_written(tmp_path: Path) -> None:
    commands = [c for page in RUN_PAGES for c in documented_commands((DOCS / page).read_text())]
    with emulate_process(REPO / "fixtures" / "benches" / "emulator.toml", 1.0, {"fatek-tcp": "--fatek-tcp"}) as where:
        failed = run_documented(commands, tmp_path, f"fatek+tcp://{where['fatek-tcp']}")
        # and a documented command that is broken is caught: an option hil does not have
        broken = run_documented(["hil probe --no-such-option"], tmp_path, "")
    assert not failed, "\n".join(failed)
    assert broken and "exited 4" in broken[0]
