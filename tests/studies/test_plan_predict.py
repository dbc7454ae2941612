"""``rig plan --predict`` records only the view slots its scores read.

The scores read the material interpolated at the held-out pairs (the four
nearest registered view slots of each held-out view, ``nearest4``) and at the
captured pairs nearest them. The btf stage compresses each view slot from its
own frames, so recording only those slots must give the same material there:
on a noise-free sample the same to float16 storage, whatever else the plan holds.
"""

import numpy as np
import pytest

from rig.plan import parse_plan
from sim.scene import scene_from_dict
from studies.plan_predict import BLENDED, COMPONENTS, SENSOR_SCALE, TEXELS, btf_only, scored_views
from studies.render_loop import (
    HELD_OUT,
    SCENES,
    captured_pairs,
    interpolated,
    process,
    reconstructed,
    record,
    truncated,
)

#: float16's relative precision (the material's storage): a slot's PCA over its
#: lights in another order may round one step differently.
FLOAT16_EPS = 2.0**-11

#: 11 views at the default rig's camera angles × 7 lights; the held-out views read 9 of them.
PLAN = """
[sample]
name = "restricted"
[captures.btf]
views = [[0, 0], [30, 0], [30, 60], [30, 120], [30, 180], [30, 240], [30, 300],
         [60, 0], [60, 90], [60, 180], [60, 270]]
lights = [[15, 0], [15, 120], [15, 240], [45, 0], [45, 90], [45, 180], [45, 270]]
[exposure]
exposure_s = 0.02
hdr_brackets = [2.5, 1.0]
"""


def test_every_view_as_near_as_the_fourth_is_read_ties_included():
    ring = np.array([[30.0, phi] for phi in range(0, 360, 45)])
    read = scored_views(ring, [((30.0, 0.0), (45.0, 0.0))])
    # 0° itself, ±45°, and ±90° tied for the fourth place
    assert ring[read, 1].tolist() == [0.0, 45.0, 90.0, 270.0, 315.0]


def test_a_view_that_did_not_register_gives_way_to_the_next_nearest():
    ring = np.array([[30.0, phi] for phi in range(0, 360, 30)])
    held_out = [((30.0, 10.0), (45.0, 0.0))]
    read = scored_views(ring, held_out)
    assert len(read) == BLENDED and 0 in read
    again = scored_views(ring, held_out, failed={0})
    assert 0 not in again and len(again) == BLENDED
    assert set(read) - {0} < set(again)


def test_the_recorded_plan_holds_the_read_views_one_exposure_and_no_other_capture():
    plan = parse_plan(
        PLAN + "[captures.ps]\nviews = [[0, 0]]\nlights = {theta_deg = 45, count = 4}\n"
    )
    views = plan.captures.btf.views.resolve().directions
    proxy = parse_plan(btf_only(plan, views[[0, 3]]))
    assert proxy.captures.ps is None and proxy.captures.mdf is None
    assert proxy.captures.btf.views.resolve().directions.tolist() == [[0, 0], [30, 120]]
    # the btf stage reads a step's first bracket: 2.5 × 0.02 s
    assert proxy.exposure.hdr_brackets == (1.0,)
    assert proxy.exposure.exposure_s == pytest.approx(0.05)


@pytest.mark.slow  # two simulated sessions (77 and 63 frames) and their btf stage: ~30 s
def test_the_read_view_slots_alone_give_the_whole_plans_scores(tmp_path):
    spec = dict(SCENES["bumps"], effects=["shadows"], render={"scale": SENSOR_SCALE})
    scene = scene_from_dict(spec)  # no sensor noise: its draws follow the frame order
    plan = parse_plan(PLAN)
    views = plan.captures.btf.views.resolve().directions
    read = scored_views(views, HELD_OUT)
    assert 0 < len(read) < len(views)
    # Each texel at its capture's own light: the two sessions turn the turntable by other
    # paths and realise some lamps 0.07–0.24 mm apart, which moves the per-texel light
    # resampling's hull rim (below).
    materials, resampled = [], []
    for name, subset in (("whole", None), ("read", views[read])):
        (tmp_path / name).mkdir()
        archive, _ = record(scene, btf_only(plan, subset), tmp_path / name)
        materials.append(process(archive, size=TEXELS, components=max(COMPONENTS),
                                 lights="nominal"))  # fmt: skip
        resampled.append(process(archive, size=TEXELS, components=max(COMPONENTS)))
    whole, part = materials
    assert len(part.btf.view_dirs_deg) == len(read) < len(whole.btf.view_dirs_deg)
    peak = float(np.abs(whole.btf.mean).max())
    # with the default per-texel lights the scores still agree within 0.5 % of the peak
    held = [interpolated(m.btf, np.asarray(m.btf_slot_valid, bool), HELD_OUT) for m in resampled]
    np.testing.assert_allclose(held[1], held[0], rtol=0, atol=5e-3 * peak)
    for c in COMPONENTS:
        seen = []
        for material in (whole, part):
            btf, valid = truncated(material.btf, c), np.asarray(material.btf_slot_valid, bool)
            assert valid.all()
            pairs = captured_pairs(btf, valid, HELD_OUT)
            directions = [(*btf.view_dirs_deg[j], *btf.light_dirs_deg[i]) for j, i in pairs]
            seen.append((directions, interpolated(btf, valid, HELD_OUT),
                         reconstructed(btf, pairs)))  # fmt: skip
        (dirs_whole, held_whole, at_whole), (dirs_part, held_part, at_part) = seen
        np.testing.assert_allclose(dirs_part, dirs_whole, atol=1e-9)
        np.testing.assert_allclose(held_part, held_whole, rtol=0, atol=4 * FLOAT16_EPS * peak)
        np.testing.assert_allclose(at_part, at_whole, rtol=0, atol=4 * FLOAT16_EPS * peak)
