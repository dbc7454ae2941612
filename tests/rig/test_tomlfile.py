"""Writing a TOML file: a reader, or a write cut off part way, sees the old file or the
new one, never half of one."""

from __future__ import annotations

from pathlib import Path

import pytest

from rig.config import default_rig_config, load_rig_config, write_rig_config


def test_a_write_cut_off_part_way_leaves_the_old_file_whole_and_no_temporary(tmp_path, monkeypatch):
    path = tmp_path / "sim-rig.toml"
    old = default_rig_config()
    write_rig_config(old, path)
    new = old.model_copy(update={"name": "renamed"})
    write_text = Path.write_text

    def full_disk(self: Path, text: str, *args, **kwargs):
        write_text(self, text[: len(text) // 2], *args, **kwargs)
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(Path, "write_text", full_disk)
    with pytest.raises(OSError, match="No space"):
        write_rig_config(new, path)
    monkeypatch.undo()
    assert load_rig_config(path) == old
    assert [p.name for p in tmp_path.iterdir()] == ["sim-rig.toml"]
    write_rig_config(new, path)
    assert load_rig_config(path).name == "renamed"
