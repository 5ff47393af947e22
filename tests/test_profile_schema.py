"""The profile's keys are declared once (hil.bench.schema): the loader, the JSON Schema for editors, ``hil init``'s
template and the docs' tables are generated from the declarations, and say the same keys (issue 41, item 2)."""

from __future__ import annotations

import json
import re
import tomllib
from pathlib import Path

import pytest

from hil.bench.family import families
from hil.bench.profile import CORE_SECTIONS, load_profile
from hil.bench.profile_keys import CORE
from hil.bench.schema_export import (
    SCHEMA_FILE,
    declared_sections,
    generated,
    json_schema,
    markdown,
    undeclared_sections,
)
from hil.cli.init import Found, render_profile
from hil.core.errors import ProfileError
from tests.conftest import REPO

FOUND = Found(status="RUN", chip=3, rate_code_reachable=True,
              temperature={"table": "R3000", "readings": "R3020", "work": "R3060", "modules": [("16TC", "K")]})


def test_the_committed_schema_is_what_the_declarations_generate() -> None:
    assert SCHEMA_FILE.read_text(encoding="utf-8") == generated()[SCHEMA_FILE], (
        f"{SCHEMA_FILE} differs from the declarations: run `python -m hil.bench.schema_export` and commit it")


def _keys_by_section(text: str, header: str, key: str) -> dict[str, list[str]]:
    """Each section's keys in ``text``: a line matching ``header`` (group 1: the section) opens a section, lines
    matching ``key`` (group 1: the key) after it list its keys."""
    out: dict[str, list[str]] = {}
    section = None
    for line in text.splitlines():
        opened = re.fullmatch(header, line)
        if opened:
            section = out.setdefault(opened.group(1), [])
        elif section is not None and (found := re.match(key, line)):
            section.append(found.group(1))
    return out


def _docs_keys() -> dict[str, list[str]]:
    """Each section's keys as the generated docs' tables list them."""
    return _keys_by_section(markdown(), r"## \[([\w.]+)\].*", r"\| `(\w+)` \|")


def _template_keys(text: str) -> dict[str, list[str]]:
    """Each section's keys as ``hil init`` writes them, set or commented out."""
    return _keys_by_section(text, r"(?:# )?\[\[?([\w.]+)\]\]?", r"(?:# )?(\w+) = ")


def test_the_keys_appear_in_one_declaration_and_everything_says_the_same() -> None:
    sections = declared_sections()
    names = [s.name for s in sections]
    assert len(names) == len(set(names)), "a section declared twice"
    for section in sections:
        keys = [k.name for k in section.keys]
        assert len(keys) == len(set(keys)), f"[{section.name}] declares a key twice"
    declared = {s.name: [k.name for k in s.keys] for s in sections}
    tables = {name: next(iter(body["properties"].values())) if name in {s.name for s in sections if s.named} else body
              for name, body in json_schema()["properties"].items()}
    schema = {name: list(body["properties"]) for name, body in tables.items() if "properties" in body}
    assert schema == declared
    assert _docs_keys() == declared
    # hil init writes every key of the core's and the FBs family's sections, set or as a commented placeholder
    fbs = {s.name for s in families()["fbs"].declarations}
    named = {s.name for s in sections if s.named}  # [faults.sensor_break]: a table of [faults]
    written = {(name.split(".")[0] if name.split(".")[0] in named else name): keys
               for name, keys in _template_keys(render_profile("b", "emulator", FOUND)).items()}
    template = {name: keys for name, keys in written.items() if name in declared}  # not [[pid.instances]]
    assert template == {name: keys for name, keys in declared.items() if name in fbs or name in {s.name for s in CORE}}


def test_every_section_a_profile_may_have_is_declared_or_said_to_be_not() -> None:
    readable = set(CORE_SECTIONS) | {s for plugin in families().values() for s in plugin.sections}
    assert {s.name for s in declared_sections()} | set(undeclared_sections()) == readable
    assert set(json_schema()["properties"]) == readable


def _walk(data: dict, schema: dict, where: str) -> list[str]:
    """The keys of ``data`` the schema does not describe (enough of JSON Schema for the bundled profiles)."""
    bad = []
    for key, value in data.items():
        body = schema.get("properties", {}).get(key)
        if body is None:
            if schema.get("additionalProperties", True) is False:
                bad.append(f"{where}.{key}")
            continue
        if isinstance(value, dict) and "properties" in body:
            bad += _walk(value, body, f"{where}.{key}")
    return bad


@pytest.mark.parametrize("name", ["emulator", "example-bench", "s7-200smart", "example-s7-200smart"])
def test_the_bundled_profiles_fit_the_schema(name: str) -> None:
    data = tomllib.loads((REPO / "fixtures" / "benches" / f"{name}.toml").read_text())
    assert _walk(data, json_schema(), name) == []


def test_init_points_editors_at_the_schema_and_its_profile_loads(tmp_path: Path) -> None:
    text = render_profile("b", "emulator", FOUND)
    first = text.splitlines()[0]
    assert first.startswith("#:schema file://") and Path(first.split("file://", 1)[1]).is_file()
    (tmp_path / "bench.toml").write_text(text)
    profile = load_profile(tmp_path / "bench.toml")
    assert profile.rtc.chip == 3 and profile.safety.writable == ("R4128-R4134", "M1952-M1953", "D4054")
    assert json.loads(SCHEMA_FILE.read_text())["properties"]["bench"]["required"] == ["name"]


# The errors: the file, the line, the section and key, and what to write.
@pytest.mark.parametrize("text, message", [
    ('[bench]\nname = "b"\n# a comment\nstation = 300\n', r"bench\.toml:4: \[bench\] station = 300 must be 1–254$"),
    ('[bench]\nname = "b"\ncolour = "red"\n', r"bench\.toml:3: unknown key\(s\) in \[bench\]: colour$"),
    ('[bench]\nstation = 2\n', r"bench\.toml:1: \[bench\] name is required \(such as name = \"oven-line-1\"\)$"),
    ('[bench]\nname = "b"\ntime_scale = "fast"\n', r"bench\.toml:3: \[bench\] time_scale must be a float, not 'fast'$"),
    ('[bench]\nname = "b"\n\n[rtc]\nchip = "DS1307"\n', r"bench\.toml:5: \[rtc\] chip: chip must be 0–3 or one of"),
    ('[bench]\nname = "b"\n[safety]\nwritable = ["R99999"]\n',
     r"bench\.toml:4: \[safety\] writable: 'R99999' is outside"),
    ('[bench]\nname = "b"\n[plant]\n[plant.points.3]\ntau = 0\n',
     r"bench\.toml:5: \[plant\.points\.3\] tau = 0\.0 must be 0\.1–1e\+06 s$"),
    ('[bench]\nname = "b"\n[plant]\npoints = 3\n', r"bench\.toml:4: \[plant\] points must be a table, not 3$"),
    ('[bench]\nname = "b"\n[emulator]\nscan_time_range = [5, 15]\n',
     r"bench\.toml:4: \[emulator\] scan_time_range varies the scans in bench timing only: add timing = \"bench\""),
    ('[bench]\nname = "b"\n\n[extras]\n', r"bench\.toml:4: unknown section \[extras\] \(known: "),
    ('[bench]\nname = "b"\nfamily = "s7-200smart"\n[s7rtc]\nset_trigger = "V100.0"\n',
     r"bench\.toml:4: \[s7rtc\] read_trigger is required \(such as read_trigger = \"V100.1\"\)$"),
    ('[bench]\nname = "b"\n[temperature]\ntable = "R3000"\nreadings = "R3020"\nwork = "R3060"\nmodules = []\n',
     r"bench\.toml:7: \[temperature\] modules: must be a non-empty list"),
    ('[bench]\nname = "b"\n[[pid.instances]]\nname = "a"\n[[pid.instances]]\nname = "c"\nsv = "R4100"\n',
     r"bench\.toml:7: \[pid\] instances\[1\] sv: R4100 is not a FUN86 register operand"),
    ('[bench]\nname = "b"\n[pid]\nzn = 0\n', r"bench\.toml:4: \[pid\] zn = 0 must be 1–32$"),
    ('[bench]\nname = "b"\n[faults.sensor_break]\nkind = "plc-bit"\nfirst = "R40"\n',
     r"bench\.toml:5: \[faults\.sensor_break\] first: R40 is not a bit \(e\.g\. first = \"Y40\"\)$"),
    ('[bench]\nname = "b"\n[faults.sensor_break]\nkind = "plc-bit"\nfirst = "Y40"\nfirst_coil = 2\n',
     r"bench\.toml:6: \[faults\.sensor_break\]: unknown key\(s\) for kind = 'plc-bit': "
     r"first_coil \(known: first, kind\)$"),
    ('[bench]\nname = "b"\n[faults.ssr_short]\nkind = "modbus-coil"\n',
     r"bench\.toml:3: \[faults\.ssr_short\] target is required with kind = 'modbus-coil' \(such as target = "),
])
def test_errors_name_the_file_line_key_and_what_to_write(tmp_path: Path, text: str, message: str) -> None:
    (tmp_path / "bench.toml").write_text(text)
    with pytest.raises(ProfileError, match=message):
        load_profile(tmp_path / "bench.toml")
