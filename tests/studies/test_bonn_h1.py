"""``rig bench bonn-h1``: the options that need a folder say so (the session itself takes
hours; its quick mode is the first view's 81 pairs)."""

import pytest

from studies.bonn_h1 import run


def test_measuring_without_a_folder_names_the_option():
    with pytest.raises(ValueError, match="measure_only needs out_dir"):
        run(measure_only=True)
