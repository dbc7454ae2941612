"""The ``material/`` group: processing results, each replaced as a whole.

A result (a zarr array or group named ``name``) is replaced by writing the new
one under a hidden temporary name and swapping it in with two renames:

1. ``material/.tmp-<name>-<token>`` is written completely (and ``fsync``-ed);
2. the old ``material/<name>``, if any, is renamed ``.old-<name>-<token>``;
3. the temporary is renamed ``material/<name>``; the old one is deleted.

A crash leaves at most one of those states; ``recover_material`` resolves it
on the next writable open: temporaries are moved to the quarantine, and an
``.old-`` copy is either moved there too (the new result is in place) or
renamed back (it is not).
"""

from __future__ import annotations

import contextlib
import logging
import os
import re
import shutil
import uuid
from collections.abc import Iterator
from pathlib import Path

from rig.archive._errors import ArchiveError
from rig.archive._quarantine import Quarantine
from rig.archive._store import check_name, fsync_dir

__all__ = ["fsync_tree", "recover_material", "replace_result"]

log = logging.getLogger(__name__)

_OLD_RE = re.compile(r"\.old-(.+)-[0-9a-f]{32}")


def fsync_tree(root: Path) -> None:
    """``fsync`` every file and directory under ``root`` (zarr does not)."""
    for directory, _, files in os.walk(root):
        for name in files:
            fd = os.open(os.path.join(directory, name), os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
        fsync_dir(Path(directory))


@contextlib.contextmanager
def replace_result(material_dir: Path, name: str, *, fsync: bool) -> Iterator[Path]:
    """Yield a fresh directory to write result ``name`` into; swap it in on success.

    On an exception the temporary is deleted and the old result stays.
    """
    token = uuid.uuid4().hex
    tmp = material_dir / f".tmp-{name}-{token}"
    old = material_dir / f".old-{name}-{token}"
    final = material_dir / name
    tmp.mkdir()
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    if fsync:
        fsync_tree(tmp)
    had_old = final.exists()
    if had_old:
        os.rename(final, old)
    os.rename(tmp, final)
    if fsync:
        fsync_dir(material_dir)
    if had_old:
        shutil.rmtree(old)


def recover_material(material_dir: Path, quarantine: Quarantine) -> list[str]:
    """Finish or roll back replacements a crash interrupted; what was done.

    Nothing is deleted: an unfinished or superseded copy goes to ``quarantine``.
    """
    actions = []
    for entry in sorted(material_dir.iterdir()):
        if entry.name.startswith(".tmp-"):
            quarantine.move(entry)
            actions.append(f"set aside unfinished {entry.name}")
            continue
        match = _OLD_RE.fullmatch(entry.name)
        if match is None:
            continue
        try:
            name = check_name(match.group(1), what=f"{entry}: material result name")
        except ArchiveError:
            quarantine.move(entry)
            actions.append(f"set aside {entry.name} (not a valid result name)")
            continue
        final = material_dir / name
        if final.exists():
            quarantine.move(entry)
            actions.append(f"set aside replaced {entry.name}")
        else:
            os.rename(entry, final)
            actions.append(f"restored {final.name} from {entry.name}")
    for action in actions:
        log.warning("%s: %s", material_dir, action)
    return actions
