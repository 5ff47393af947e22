"""Where the project's suites and bench profiles are, whether hil runs from a checkout or an installed wheel.

The suites and fixtures live at the top of the repository (where the README points); ``hil/_data/suites`` and
``hil/_data/fixtures`` are symlinks to them, so an editable install reads the checkout and a wheel (setuptools
copies what the links point to, see ``[tool.setuptools.package-data]``) carries its own copy.

And where a bench's locks and journals are (:func:`bench_dir`): one directory for every user of the bench, the
bench group's (mode 2770, files 0660), so a run finds — and recovers — a journal another user's dead run left.
"""

from __future__ import annotations

import grp
import os
import pwd
import stat
from pathlib import Path

from hil.core.errors import HilError

#: The bundled suites and fixtures (symlinks in a checkout, real directories in an installed wheel).
BUNDLED = Path(__file__).resolve().parent.parent / "_data"


def project_dir(name: str) -> Path:
    """``suites`` or ``fixtures`` from the current directory if it has one (a user's own), else the bundled."""
    here = Path.cwd() / name
    return here if here.exists() else BUNDLED / name


def default_bench() -> Path:
    return project_dir("fixtures") / "benches" / "emulator.toml"


def _bench_dirs() -> list[Path]:
    """Where short profile names are looked up: this directory's fixtures/benches, then the bundled ones."""
    dirs = [Path.cwd() / "fixtures" / "benches", BUNDLED / "fixtures" / "benches"]
    return [d for n, d in enumerate(dirs) if d.is_dir() and d.resolve() not in {e.resolve() for e in dirs[:n]}]


def bundled_benches() -> dict[str, Path]:
    """Every profile reachable by short name (``s7-200smart``), the first directory's copy where both have one."""
    found: dict[str, Path] = {}
    for directory in _bench_dirs():
        for path in sorted(directory.glob("*.toml")):
            found.setdefault(path.stem, path)
    return found


def bench_path(given: str | Path) -> Path:
    """A bench profile given as a path, or by the short name of a bundled one (``--bench s7-200smart``), or as the
    README spells them (``fixtures/benches/s7-200smart.toml``) where this directory has none: a file that exists
    always wins, so a name never hides a user's own profile."""
    path = Path(given)
    if path.exists() or path.is_absolute():
        return path
    if path.parts[:1] == ("fixtures",) and (BUNDLED / path).is_file():  # the README's fixtures/benches/…, installed
        return BUNDLED / path
    if len(path.parts) == 1 and path.suffix in ("", ".toml"):
        return bundled_benches().get(path.stem, path)
    return path


def suites_dir() -> Path:
    return project_dir("suites")


def bundled_suites() -> dict[str, Path]:
    """Every suite by short name — the file without ``test_`` (``rtc``, ``rtc_validity``), a directory of suites
    by its name (``s7smart``) — so ``hil run -- rtc`` works in a checkout and from an installed wheel alike."""
    root = suites_dir()
    found: dict[str, Path] = {}
    for path in sorted(root.rglob("test_*.py")):
        found.setdefault(path.stem.removeprefix("test_"), path)
    for path in sorted(p for p in root.iterdir() if p.is_dir() and any(p.glob("test_*.py"))):
        found.setdefault(path.name, path)
    return found


def suite_path(arg: str) -> str | None:
    """The test path a ``hil run`` argument means, when it is a suite's short name (``rtc``, ``rtc::test_x``,
    ``rtc-validity``) or a path under ``suites/`` that this directory does not have (the README's
    ``suites/test_rtc.py`` once installed); None for anything else (left to pytest as given)."""
    path, sep, rest = arg.partition("::")
    if Path(path).exists():
        return None
    named = bundled_suites().get(path.replace("-", "_"))
    if named is not None:
        return f"{named}{sep}{rest}"
    parts = Path(path).parts
    if len(parts) > 1 and parts[0] == "suites" and (suites_dir().joinpath(*parts[1:])).exists():
        return f"{suites_dir().joinpath(*parts[1:])}{sep}{rest}"
    return None


# -- the bench directory: where every user of a bench finds its locks and journals -----------------------------------
#: the bench directory (locks and journals); the default is the same for every user of the host
BENCH_DIR_ENV = "HIL_LOCK_DIR"
#: the group whose members share the bench directory (a name or a number); unset: the directory's own group,
#: which must be one of yours
BENCH_GROUP_ENV = "HIL_BENCH_GROUP"
#: persistent across reboots (a journal must outlive a power cut), unlike /run/lock
DEFAULT_BENCH_DIR = Path("/var/tmp/hil")
#: the directory's mode: the group's members read and write, the setgid bit gives every file the directory's group
BENCH_DIR_MODE = 0o2770
#: a lock's or a journal's mode in it: the bench group's members take the lock and recover the journal
BENCH_FILE_MODE = 0o660


def bench_dir() -> Path:
    """The bench directory (not created or checked: :func:`prepare_bench_dir`): ``$HIL_LOCK_DIR``, else
    ``/var/tmp/hil`` — one place for every user of the host, so one user's run finds what another's left."""
    given = os.environ.get(BENCH_DIR_ENV)
    return Path(given) if given else DEFAULT_BENCH_DIR


def bench_group() -> int | None:
    """The configured bench group's id (``$HIL_BENCH_GROUP``), None when not configured."""
    given = os.environ.get(BENCH_GROUP_ENV, "").strip()
    if not given:
        return None
    if given.isdigit():
        return int(given)
    try:
        return grp.getgrnam(given).gr_gid
    except KeyError:
        raise HilError(f"{BENCH_GROUP_ENV}={given}: no such group — name an existing group (getent group) or "
                       f"unset it") from None


def prepare_bench_dir(directory: Path | None = None) -> Path:
    """Create the bench directory (mode 2770, the bench group's) or check the one there; refuse one that is not
    safe to share (:func:`bench_dir_problem`), saying what to do."""
    directory = Path(directory) if directory else bench_dir()
    group = bench_group()
    try:
        directory.parent.mkdir(parents=True, exist_ok=True)
        directory.mkdir(mode=0o700)  # nobody else's until it has its group and mode
    except FileExistsError:
        pass
    except OSError as exc:
        raise HilError(f"cannot create the bench directory {directory}: {exc} — create it (mkdir -m 2770 "
                       f"{directory}; chgrp BENCH-GROUP {directory}) or set {BENCH_DIR_ENV} to one you can write"
                       ) from None
    else:
        try:
            if group is not None:
                os.chown(directory, -1, group)
            os.chmod(directory, BENCH_DIR_MODE)  # mkdir's mode is cut by the umask and cannot set setgid
        except OSError as exc:
            raise HilError(f"cannot give the bench directory {directory} its group and mode 2770: {exc}") from None
    problem = bench_dir_problem(directory, group)
    if problem:
        raise HilError(problem)
    return directory


def share_with_bench(fd: int, directory: Path) -> None:
    """Make a file hil creates in the bench directory the bench's: mode 0660 and the directory's group (which a
    setgid directory gives it already, one without does not) — or 0600 where it cannot have that group (yours
    alone, never writable by a group that is not the bench's)."""
    try:
        if os.fstat(fd).st_gid != os.stat(directory).st_gid:
            os.fchown(fd, -1, os.stat(directory).st_gid)
        os.fchmod(fd, BENCH_FILE_MODE)  # open's mode is cut by the umask
    except PermissionError:
        os.fchmod(fd, 0o600)


def _group_name(gid: int) -> str:
    try:
        return f"{grp.getgrgid(gid).gr_name} ({gid})"
    except KeyError:
        return str(gid)


def user_name(uid: int) -> str:
    """The login name of ``uid`` (its number where it has none)."""
    try:
        return pwd.getpwuid(uid).pw_name
    except KeyError:
        return str(uid)


def user_and_uid(uid: int) -> str:
    name = user_name(uid)
    return f"{name} (uid {uid})" if name != str(uid) else f"uid {uid}"


def _my_groups() -> set[int]:
    return {os.getegid(), *os.getgroups()}


def bench_dir_problem(directory: Path, group: int | None = None) -> str | None:
    """Why ``directory`` must not hold a bench's locks and journals, None when it may: a real directory, owned by
    you or root, writable by nobody outside its group, and that group the bench group (or one of yours)."""
    try:
        info = os.lstat(directory)
    except OSError as exc:
        return f"cannot check the bench directory {directory}: {exc}"
    mode = stat.S_IMODE(info.st_mode)
    shown = (f"the bench directory {directory} (mode {mode:04o}, owner {user_and_uid(info.st_uid)}, group "
             f"{_group_name(info.st_gid)})")
    fix = (f"have its owner or an administrator make it the bench group's (chgrp BENCH-GROUP {directory} && "
           f"chmod 2770 {directory}; {BENCH_GROUP_ENV}=BENCH-GROUP for every user of the bench), or point "
           f"{BENCH_DIR_ENV} at the directory every user of this bench shares")
    if not stat.S_ISDIR(info.st_mode):
        return f"{shown} is not a directory (a symbolic link or a file) — refusing to use it; {fix}"
    if mode & 0o002:
        return (f"{shown} is writable by everyone — refusing to use it: anyone could plant or remove a lock or a "
                f"journal there; {fix}")
    if mode & stat.S_ISVTX and mode & 0o020:
        return (f"{shown} has the sticky bit — refusing it: one user of the bench could not put back or clear "
                f"another's journal; chmod 2770 {directory}")
    if info.st_uid not in (os.getuid(), 0) and (info.st_gid not in _my_groups() or not mode & 0o070):
        return f"{shown} belongs to another user and is not shared with a group of yours — refusing it; {fix}"
    if group is not None and info.st_gid != group:
        return (f"{shown} is not the bench group {_group_name(group)}'s ({BENCH_GROUP_ENV}) — refusing it; "
                f"chgrp {group} {directory} && chmod 2770 {directory}")
    if group is None and mode & 0o020 and info.st_gid not in _my_groups():
        return (f"{shown} is writable by a group you are not in — refusing it: its members could plant a "
                f"journal; {fix}")
    return None


def bench_file_problem(path: Path, info: os.stat_result) -> str | None:
    """Why a lock or journal file ``path`` (its ``info``) in the bench directory must not be trusted, None when it
    may: a plain file with one link, writable by nobody outside the directory's group, and its owner one who could
    have written it there (you, root, the directory's owner or a member of its group)."""
    mode = stat.S_IMODE(info.st_mode)
    shown = f"{path} (mode {mode:04o}, owner {user_and_uid(info.st_uid)}, group {_group_name(info.st_gid)})"
    if not stat.S_ISREG(info.st_mode):
        return f"{shown} is not a plain file — refusing to trust it (kept; check it by hand)"
    if info.st_nlink != 1:
        return f"{shown} has {info.st_nlink} hard links — refusing to trust it (kept; check it by hand)"
    if mode & 0o002:
        return f"{shown} is writable by others — refusing to trust it (kept; check it, then chmod 0660 it)"
    directory = os.stat(path.parent)
    if mode & 0o020 and info.st_gid != directory.st_gid:
        return (f"{shown} is writable by a group other than the bench directory's — refusing to trust it (kept; "
                f"check it, then chgrp {directory.st_gid} it)")
    if not _could_write(info.st_uid, directory):
        return (f"{shown} belongs to uid {info.st_uid}, who cannot write the bench directory {path.parent} — "
                f"refusing to trust it: someone put it there (kept; check it by hand)")
    return None


def _could_write(uid: int, directory: os.stat_result) -> bool:
    """Whether user ``uid`` could have created a file in ``directory`` (root, its owner, or its group's member)."""
    if uid in (0, os.getuid(), directory.st_uid):
        return True
    if not directory.st_mode & 0o020:
        return False
    try:
        user = pwd.getpwuid(uid)
        members = grp.getgrgid(directory.st_gid).gr_mem
    except KeyError:
        return False
    return user.pw_gid == directory.st_gid or user.pw_name in members
