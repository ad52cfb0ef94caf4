"""Other LiDAR drivers' clouds (issue 34): a PCD saved as pcl_ros saves one and a numpy structured
array, read by the field names bags share (docs/bags.md, "Point clouds of other drivers")."""
import numpy as np

import lidartag
from conftest import DEMO_SIZES


def _robosense_cloud(rotation):
    """The rotation as RoboSense's driver publishes it (XYZIRT: x y z intensity float, ring uint16,
    2 bytes of padding, timestamp double seconds since the epoch), as a numpy structured array."""
    p = rotation.points
    cloud = np.zeros(len(p), dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("_", "V4"),
                                     ("intensity", "<f4"), ("ring", "<u2"), ("__", "V2"),
                                     ("timestamp", "<f8")])
    for name in ("x", "y", "z", "intensity", "ring"):
        cloud[name] = p[name]
    cloud["timestamp"] = rotation.stamp_ns * 1e-9 + p["time"].astype(np.float64)
    return cloud


def test_another_drivers_pcd_and_array_give_the_tags_of_the_rotation(demo_rotations, tmp_path):
    # Issue 34: a RoboSense cloud saved as pcl_ros saves it (PCL's `_` padding fields, binary) and
    # the same cloud as a numpy structured array: read by the field names bags share (`timestamp`
    # in seconds since the epoch as the time), the tags where the detector finds them on the
    # rotation itself.
    rotation = next(r for r in demo_rotations if r.complete)
    detector = lidartag.Detector(DEMO_SIZES)
    direct = {d.id: np.asarray(d.position) for d in detector.detect(rotation)}
    assert len(direct) == 2
    cloud = _robosense_cloud(rotation)
    path = tmp_path / "robosense.pcd"
    header = ("VERSION 0.7\nFIELDS x y z _ intensity ring _ timestamp\nSIZE 4 4 4 1 4 2 1 8\n"
              "TYPE F F F U F U U F\nCOUNT 1 1 1 4 1 1 2 1\n"
              f"WIDTH {len(cloud)}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {len(cloud)}\n"
              "DATA binary\n")
    path.write_bytes(header.encode() + cloud.tobytes())
    assert set(lidartag.read_pcd(path)["fields"]) == {"x", "y", "z", "intensity", "ring",
                                                      "timestamp"}
    from_pcd = next(iter(lidartag.read(path)))
    from_array = lidartag.Rotation.from_points(cloud)
    for rebuilt in (from_pcd, from_array):
        assert rebuilt.rings == 32 and len(rebuilt) > 0.98 * len(rotation)
        times = rebuilt.arrays()["time"][rebuilt.arrays()["valid"]]
        assert times.min() >= 0 and 0.09 < times.max() < 0.11  # seconds from the sweep's start
        found = {d.id: np.asarray(d.position) for d in detector.detect(rebuilt)}
        assert set(found) == set(direct)
        for tag, position in direct.items():
            assert np.linalg.norm(found[tag] - position) < 0.02, tag
