"""Property: recovery and repair never read, move or write anything outside their archive.

Hypothesis plants random trees into a small archive: real folders and files
under chunk and material names, and links (to folders, files, missing
targets, inside and outside the archive) in place of its own parts or beside
them; it may also cut the journal (leftover chunks to recover). Then the
archive is opened for appending (recovery) or repaired. A Python audit hook
records every path opened, listed, renamed, removed or created meanwhile, and
none may resolve into the tree outside; that tree must be byte for byte as
before, links included.
"""

import os
import shutil
import sys
import tempfile
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rig.archive import Archive, ArchiveError, repair_archive
from tests.rig.archive.sessions import build_session

N_STEPS = 4
_TEMPLATE = Path(tempfile.mkdtemp(prefix="btfrig-containment-")) / "template.zarr"
build_session(_TEMPLATE, N_STEPS)

#: Where planted entries go, relative to the archive root.
_FOLDERS = ["", "frames", "frames/cam0", "frames/cam1", "material", "log", "calibration"]
#: Names that recovery and repair look at, and one they do not.
_NAMES = [
    "c.8.0.0.0",
    "c.9.0.0.0",
    "c.999.0.0.0",
    ".tmp-normals-" + "a" * 32,
    ".old-normals-" + "b" * 32,
    "normals",
    "quarantine",
    "writer.lock",
    "x",
]
#: An archive's own parts that a link may replace.
_OWN = [
    "frames",
    "frames/cam0",
    "frames/cam1",
    "frames/cam0/zarr.json",
    "material",
    "log",
    "log/journal.jsonl",
    "calibration",
    "calibration/zarr.json",
    "zarr.json",
]
#: Link targets outside (the other archive's parts, plain files and folders, nothing).
_OUTSIDE = ["other.zarr", "other.zarr/frames/cam0", "other.zarr/frames/cam0/c.1.0.0.0",
            "other.zarr/material", "other.zarr/log/journal.jsonl", "plain.txt", "folder",
            "missing"]  # fmt: skip

_watch: list = []  # [outside root (real path), paths seen there]


def _real(path, *, follow: bool) -> str | None:
    if isinstance(path, bytes):
        path = os.fsdecode(path)
    if not isinstance(path, str | os.PathLike):
        return None  # a file descriptor
    path = os.path.abspath(path)
    if follow:
        return os.path.realpath(path)
    # Without following the last component: where the entry itself sits.
    return os.path.join(os.path.realpath(os.path.dirname(path)), os.path.basename(path))


def _audit(event: str, args: tuple) -> None:
    if not _watch:
        return
    outside, seen = _watch
    if event == "open":
        paths = [(args[0], not (isinstance(args[2], int) and args[2] & os.O_NOFOLLOW))]
    elif event in ("os.scandir", "os.listdir"):
        paths = [(args[0], True)]
    elif event in ("os.rename", "os.link"):
        paths = [(args[0], False), (args[1], False)]
    elif event in ("os.remove", "os.rmdir", "os.mkdir", "os.symlink", "shutil.rmtree"):
        paths = [(args[1] if event == "os.symlink" else args[0], False)]
    elif event in ("os.truncate", "os.chmod", "os.utime", "os.chown"):
        paths = [(args[0], True)]
    else:
        return
    for path, follow in paths:
        real = _real(path, follow=follow)
        if real is not None and (real == outside or real.startswith(outside + os.sep)):
            seen.append((event, str(path)))


sys.addaudithook(_audit)


def _snapshot(root: Path) -> dict[str, tuple]:
    """Every entry under ``root``, links not followed: its kind and its content or target."""
    tree = {}
    for directory, folders, files in os.walk(root):
        for name in folders + files:
            path = Path(directory, name)
            if path.is_symlink():
                tree[str(path)] = ("link", os.readlink(path))
            elif path.is_dir():
                tree[str(path)] = ("dir",)
            else:
                tree[str(path)] = ("file", path.read_bytes())
    return tree


plants = st.lists(
    st.tuples(
        st.sampled_from(_FOLDERS),
        st.sampled_from(_NAMES),
        st.sampled_from(["file", "folder", "link out", "link in"]),
        st.sampled_from(_OUTSIDE),
    ),
    max_size=4,
)
replacements = st.lists(st.tuples(st.sampled_from(_OWN), st.sampled_from(_OUTSIDE)), max_size=2)


def _plant(archive: Path, outside: Path, plan, replace, cut: int) -> None:
    journal = archive / "log" / "journal.jsonl"
    lines = journal.read_bytes().splitlines(keepends=True)
    journal.write_bytes(b"".join(lines[: len(lines) - cut]))
    for folder, name, kind, target in plan:
        where = archive / folder / name
        if where.exists() or where.is_symlink() or not where.parent.is_dir():
            continue
        if kind == "file":
            where.write_bytes(b"planted")
        elif kind == "folder":
            where.mkdir()
            (where / "zarr.json").write_bytes(b"{}")
        elif kind == "link out":
            where.symlink_to(outside / target)
        else:
            where.symlink_to(archive / "frames" / "cam0")
    for own, target in replace:
        path = archive / own
        if not (path.exists() or path.is_symlink()) or path.is_symlink():
            continue
        shutil.rmtree(path) if path.is_dir() else path.unlink()
        path.symlink_to(outside / target)


@settings(
    max_examples=30,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
@given(
    plan=plants,
    replace=replacements,
    cut=st.integers(0, 3),
    how=st.sampled_from(["recover", "read", "repair"]),
)
def test_nothing_outside_the_archive_is_touched(plan, replace, cut, how):
    with tempfile.TemporaryDirectory() as tmp:
        outside = Path(tmp, "outside")
        shutil.copytree(_TEMPLATE, outside / "other.zarr")
        (outside / "plain.txt").write_bytes(b"not the archive's")
        (outside / "folder").mkdir()
        (outside / "folder" / "c.8.0.0.0").write_bytes(b"not a chunk of it")
        archive = Path(tmp, "archive.zarr")
        shutil.copytree(_TEMPLATE, archive)
        _plant(archive, outside, plan, replace, cut)
        before = _snapshot(outside)
        seen: list = []
        _watch[:] = [os.path.realpath(outside), seen]
        try:
            if how == "repair":
                repair_archive(archive, fsync=False)
            else:
                Archive.open(archive, mode="a" if how == "recover" else "r", fsync=False).close()
        except ArchiveError:
            pass  # damage, named: the point here is what was touched meanwhile
        finally:
            _watch.clear()
        assert seen == []
        assert _snapshot(outside) == before
