"""The tetrahedron-weighted merge and the MDF assembly, on hand-made displacement images."""

import numpy as np
import pytest

from processing.mdf import MdfError, Reason, ScanDisplacement, assemble_mdf, merge_scans

OK, EDGE, UNLIT, GRAZING = Reason.OK, Reason.EDGE, Reason.UNLIT, Reason.GRAZING


def image(values, reasons, weight):
    v = np.asarray(values, np.float32)
    r = np.asarray(reasons, np.uint8)
    return ScanDisplacement(np.where(r <= EDGE, v, -1).astype(np.float32), r, weight)


def test_weighted_mean_over_locations_that_saw_the_texel():
    a = image([[1.0, 2.0, 0.0, 0.0]], [[OK, OK, UNLIT, UNLIT]], 1.0)
    b = image([[3.0, 0.0, 0.0, 5.0]], [[OK, UNLIT, GRAZING, EDGE]], 3.0)
    merged = merge_scans([a, b])
    np.testing.assert_allclose(merged.distance, [[2.5, 2.0, -1.0, 5.0]])
    assert merged.reason.tolist() == [[OK, OK, GRAZING, EDGE]]
    assert merged.count.tolist() == [[2, 1, 0, 1]]
    np.testing.assert_allclose(merged.spread_mm, [[2.0, 0.0, 0.0, 0.0]])
    assert merged.distance.dtype == np.float32


def test_zero_weight_locations_never_contribute():
    a = image([[1.0]], [[OK]], 0.0)
    b = image([[3.0]], [[OK]], 2.0)
    assert merge_scans([a, b]).distance.tolist() == [[3.0]]
    assert merge_scans([a]).distance.tolist() == [[-1.0]]


def test_merge_and_assembly_errors():
    with pytest.raises(MdfError, match="no displacement image"):
        merge_scans([])
    with pytest.raises(MdfError, match="different texel grids"):
        merge_scans([image([[1.0]], [[OK]], 1.0), image([[1.0, 2.0]], [[OK, OK]], 1.0)])
    with pytest.raises(MdfError, match="weights"):
        merge_scans([image([[1.0]], [[OK]], -1.0)])
    view = merge_scans([image([[1.0]], [[OK]], 1.0)])
    with pytest.raises(MdfError, match="one finite"):
        assemble_mdf([view], [[0.0, 0.0], [1.0, 1.0]])


def test_assembled_mdf():
    views = [
        merge_scans([image([[1.0, 2.0]], [[OK, UNLIT]], 1.0)]),
        merge_scans([image([[3.0, 4.0]], [[OK, OK]], 1.0)]),
    ]
    mdf = assemble_mdf(views, [[0.0, 0.0], [30.0, 90.0]])
    assert mdf.distance_mm.shape == (2, 1, 2) and mdf.distance_mm.dtype == np.float32
    assert mdf.reason.dtype == np.uint8 and mdf.count.dtype == np.uint8
    np.testing.assert_allclose(mdf.coverage(), [0.5, 1.0])
    assert mdf.view_dirs_deg.dtype == np.float32
