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


def luminar():
    path = CAPTURES / "bags" / "ros1" / "luminar_pointcloud2_lz4.bag"
    if not path.exists():
        pytest.skip(f"no bags in {CAPTURES / 'bags'}")
    return path


def test_a_point_cloud2_topic_reads_as_one_rotation_per_cloud():
    reader = lidartag.read(luminar(), topic="/luminar_pointcloud")
    rotations = list(reader)
    assert len(rotations) == 5
    assert reader.counts["messages"] == 5 and reader.counts["skipped_clouds"] == 0
    assert [r.sequence for r in rotations] == [0, 1, 2, 3, 4]
    # Stamped with the clouds' header stamps, 0.1 s apart (a 10 Hz sensor).
    stamps = np.array([r.stamp_ns for r in rotations])
    assert stamps[0] == 1583971570015299642
    assert np.all(np.abs(np.diff(stamps) - 100_000_000) < 2_000_000)
    # The Rotation a pcap gives, with the same points layout.
    pcap = next(iter(lidartag.read(CAPTURES / "vlp16_dual_nebula.pcap")))
    for r in rotations:
        assert isinstance(r, lidartag.Rotation) and r.complete and len(r) > 0
        assert r.points.dtype == pcap.points.dtype
        # laser_id (0 and 1: two lasers) is the ring field: two rings.
        assert r.rings == 2
    # The detector takes them as it takes a pcap's rotations: no tags in this recording.
    detector = lidartag.Detector()
    assert all(len(detector.detect(r)) == 0 for r in rotations)


def test_a_bag_time_window_and_a_wrong_topic():
    window = list(lidartag.read(luminar(), start=0.15, duration=0.2))
    assert [r.stamp_ns for r in window] == [1583971570215200989, 1583971570315396514]
    with pytest.raises(lidartag.IoError, match="no topic /nope"):
        lidartag.read(luminar(), topic="/nope")
    with pytest.raises(ValueError, match="--duration"):
        lidartag.read(luminar(), duration=0)
    with pytest.raises(ValueError, match="for ROS bags"):
        lidartag.read(CAPTURES / "vlp16_dual_nebula.pcap", topic="/velodyne_packets")
    velodyne = CAPTURES / "bags" / "rosbag2" / "vlp16_dual"
    reader = lidartag.read(velodyne, start=0.15, duration=0.2, partial=True)
    list(reader)
    assert reader.counts["data_packets"] == 301  # two VelodyneScan messages of four
    # As the whole bag is opened (driver::open_capture) and named.
    assert reader.vendor == "velodyne"
    assert reader.source == lidartag.read(velodyne).source == "ROS 2 bag (sqlite3), topic " \
        "/velodyne_packets"


def test_a_pcap_time_window_keeps_its_rotations(demo, demo_rotations, tmp_path):
    # A pcap's window counts from its first packet, as `lidartag ... --start/--duration` does: the
    # packets outside are counted, each whole rotation inside is the one the whole file gives.
    period = (demo_rotations[-1].stamp_ns - demo_rotations[0].stamp_ns) / (len(demo_rotations) - 1)
    reader = lidartag.read(demo, start=2.5 * period * 1e-9, duration=3 * period * 1e-9)
    window = list(reader)
    assert 2 <= len(window) <= 3
    assert reader.counts["outside_window"] > 0
    whole = {r.stamp_ns: r for r in demo_rotations}
    for r in window:
        assert np.array_equal(r.points, whole[r.stamp_ns].points)
    pcd = tmp_path / "one.pcd"
    lidartag.write_pcd(demo_rotations[0], pcd, "binary", False)
    with pytest.raises(ValueError, match="PCD file"):
        lidartag.read(pcd, start=1.0)
