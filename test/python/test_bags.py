"""lidartag.read on ROS 2 bags of Velodyne packets: the same rotations as the pcaps of the same
packets (../shared/captures/bags; skipped when absent)."""
import pathlib

import numpy as np
import pytest

import lidartag
from conftest import SOURCE_DIR

CAPTURES = SOURCE_DIR.parent / "shared" / "captures"
PAIRS = [("vlp16_dual", "vlp16_dual_nebula.pcap"), ("vlp32c", "vlp32c_nebula_fov.pcap"),
         ("vls128", "vls128_nebula.pcap")]


@pytest.mark.parametrize("bag,pcap", PAIRS)
def test_bag_reads_as_its_pcap(bag, pcap):
    bag_path = CAPTURES / "bags" / "rosbag2" / bag
    if not bag_path.exists():
        pytest.skip(f"no bags in {CAPTURES / 'bags'}")
    from_bag = list(lidartag.read(bag_path, partial=True))
    from_pcap = list(lidartag.read(CAPTURES / pcap, partial=True))
    assert len(from_bag) == len(from_pcap) > 1
    for b, p in zip(from_bag, from_pcap):
        assert (b.sequence, b.stamp_ns, b.complete) == (p.sequence, p.stamp_ns, p.complete)
        assert np.array_equal(b.points, p.points)
