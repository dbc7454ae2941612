"""A VirTex stage end to end: sessions through the daemon and the real drivers against the
simulated stage, then `rig process --stages ps`, checked against the simulator's truth.

Tolerances as the Wang rig's 12-lamp session (tests/integration/test_process_ps.py): bumps
sample, lamps at θ = 45°, 128² texels, no shadows: mean angular error < 1°, 95th
percentile < 2.5°; the table beside the Wang rig is docs/photometric.md's.
"""

from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

from orchestrator.cli import app
from rig.archive import Archive
from studies.ps_kinds import ps_session

# Sessions, subprocesses or benches: the full tier only (make test), not make quick.
pytestmark = pytest.mark.slow


@pytest.mark.parametrize("lamps", [3, 6])
def test_a_virtex_session_gives_normals_as_good_as_the_wang_rig(tmp_path, lamps):
    row = ps_session("virtex", lamps, [], tmp_path)
    assert row["valid"] > 0.99
    assert row["mean_deg"] < 1.0 and row["p95_deg"] < 2.5, row
    with Archive.open(row["archive"]) as archive:
        steps = archive.step_table()
    assert [s.lamp for s in steps] == [f"lamp{i}" for i in range(lamps)]
    assert all(s.actuators == {} for s in steps)  # nothing moves, nothing to record
    azimuths = np.array([s.light_deg[1] for s in steps])
    np.testing.assert_allclose(np.diff(azimuths), 360.0 / lamps, atol=1e-9)
    np.testing.assert_allclose([s.light_deg[0] for s in steps], 45.0, atol=1e-9)
    np.testing.assert_allclose([s.views_deg["cam0"][0] for s in steps], 0.0, atol=1e-9)
    assert row["session_s"] < 0.5 * lamps  # lamp warm-up and exposures only
    if lamps == 3:  # the full set of stages: what the stage cannot capture is skipped
        args = ["process", str(row["archive"]), "--stages", "ps,btf,mdf", "--size", "16"]
        result = CliRunner().invoke(app, args)
        assert result.exit_code == 0, result.output
        said = " ".join(result.output.split())  # whatever the terminal's width
        for stage in ("btf", "mdf"):
            assert (f"{stage}: skipped — the archive has no {stage} captures: its plan "
                    "captures ps, on a 'virtex' rig") in said  # fmt: skip
        assert "ps: 1 item(s) → material/ps" in said


def test_the_estimate_refuses_captures_a_virtex_stage_cannot_do(tmp_path):
    plan = tmp_path / "plan.toml"
    plan.write_text(
        '[sample]\nname = "s"\n[captures.btf]\nviews = "H1"\nlights = "H1"\n'
        "[captures.ps]\nlights = { theta_deg = 45, count = 6 }\n"
    )
    result = CliRunner().invoke(
        app, ["plan", str(plan), "--config", "examples/rigs/virtex.toml", "--estimate"]
    )
    assert result.exit_code == 2, result.output
    assert "captures.btf: a VirTex stage captures photometric stereo only" in result.output
    assert "Traceback" not in result.output
    plan.write_text('[sample]\nname = "s"\n[captures.ps]\nlights = { theta_deg = 45, count = 6 }\n')
    result = CliRunner().invoke(
        app, ["plan", str(plan), "--config", "examples/rigs/virtex.toml", "--estimate"]
    )
    assert result.exit_code == 0, result.output
