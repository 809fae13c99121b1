"""The picture cache: a file is reused only for the same picture."""

from study_helpers import study_file

from mindgap.study.config import load_study
from mindgap.study.render import Renderer


def test_a_cached_picture_is_reused_only_for_the_same_item_data(tmp_path):
    study = load_study(study_file(tmp_path, "grid7-rating"))
    renderer = Renderer(study, tmp_path / "media")
    item = {"id": "demo-00", "kind": "demo", "data": {"states": [0, 1, 2, 9], "size": 7}}
    other = {**item, "data": {"states": [0, 7, 14, 15], "size": 7}}
    first = renderer.path(item, "demo", "")
    assert renderer.path(item, "demo", "") == first  # drawn once, then reused
    second = renderer.path(other, "demo", "")
    assert second != first and second.read_bytes() != first.read_bytes()
    assert renderer.path(item, "demo", "humanoid") != first  # the condition is part of the picture too
