"""Reading stereo pairs from ROS 1 and ROS 2 bags."""

import numpy as np
import pytest
from bagwriter import write_bag

from slitcli.errors import SlitcliError
from slitcli.io.bags import bag_frames, pair_bag

LEFT, RIGHT = "/stereo/left/image_raw", "/stereo/right/image_raw"


@pytest.fixture(scope="module")
def frames():
    # the images only need to differ: a bag round trip is byte-exact for any pixels, so
    # one seed suffices
    rng = np.random.default_rng(1)
    return [(rng.integers(0, 256, (12, 16, 3), dtype=np.uint8),
             rng.integers(0, 256, (12, 16, 3), dtype=np.uint8)) for _ in range(4)]


@pytest.mark.parametrize("ros,storage", [(1, ""), (2, "sqlite3"), (2, "mcap")])
def test_pairs_and_images_round_trip(tmp_path, frames, ros, storage):
    path = write_bag(tmp_path / ("b.bag" if ros == 1 else "b"), frames, ros=ros, storage=storage)
    pairs = pair_bag(path, LEFT, RIGHT, max_dt_s=0.01)
    assert len(pairs) == 4
    np.testing.assert_array_equal(np.diff(pairs.left_ns), 200_000_000)
    got = list(bag_frames(pairs, skip={2}))
    assert got[2] == 2
    for f in (g for g in got if not isinstance(g, int)):
        np.testing.assert_array_equal(f.left_bgr, frames[f.index][0])
        np.testing.assert_array_equal(f.right_bgr, frames[f.index][1])
        assert f.time_s == pytest.approx(1_700_000_000 + 0.2 * f.index)


def test_missing_topic_lists_the_image_topics(tmp_path, frames):
    path = write_bag(tmp_path / "b", frames, ros=2)
    with pytest.raises(SlitcliError, match=r"no topic '/cam/left'.*image topics in this bag: "
                                           r"/stereo/left/image_raw, /stereo/right/image_raw"):
        pair_bag(path, "/cam/left", RIGHT, 0.01)


def test_unpaired_explains_offset_and_time_unit(tmp_path, frames):
    path = write_bag(tmp_path / "late", frames, ros=2, right_offset_ns=80_000_000)
    with pytest.raises(SlitcliError, match=r"0\.08 s apart.*try `max_dt_s` 0\.12"):
        pair_bag(path, LEFT, RIGHT, 0.01)
    # a right camera stamping microseconds into the nanosecond field
    path = write_bag(tmp_path / "units.bag", frames, ros=1, right_divisor=1000)
    with pytest.raises(SlitcliError, match=r"factor of about 10\^3: one camera seems to stamp "
                                           r"in another time unit"):
        pair_bag(path, LEFT, RIGHT, 0.01)
