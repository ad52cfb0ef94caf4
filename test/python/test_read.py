"""Captures and PCD files into rotations as numpy arrays."""
import numpy as np
import pytest

import lidartag

FIELDS = ("x", "y", "z", "range", "azimuth", "time", "column", "ring", "intensity",
          "return_type")


def test_the_demo_capture_reads_into_its_rotations(demo, truth, demo_rotations):
    rotations = demo_rotations
    assert len(rotations) == len(truth["rotations"]) == 10
    assert len(list(lidartag.read(demo, partial=True))) == 12  # the partial first and last
    for rotation, expected in zip(rotations, truth["rotations"]):
        assert rotation.complete
        assert rotation.model == "vlp32c"
        assert rotation.return_mode == "strongest"
        assert (rotation.rings, rotation.returns) == (32, 1)
        assert abs(rotation.stamp_ns - expected["stamp_ns"]) <= 1000  # pcap: microseconds
        assert rotation.stamp == pytest.approx(expected["stamp_ns"] * 1e-9, abs=1e-6)
        assert 595 < rotation.rpm < 605
    assert [r.sequence for r in rotations] == sorted(r.sequence for r in rotations)


def test_points_and_arrays_hold_the_same_cells(demo_rotations):
    rotation = demo_rotations[0]
    points = rotation.points
    assert points.dtype.names == FIELDS
    assert points.dtype["x"] == np.float32 and points.dtype["ring"] == np.uint16
    arrays = rotation.arrays()
    shape = (rotation.returns, rotation.rings, rotation.columns)
    for name in ("x", "y", "z", "range", "intensity", "azimuth", "time", "return_type", "valid"):
        assert arrays[name].shape == shape, name
    valid = arrays["valid"]
    assert len(points) == len(rotation) == int(valid.sum()) > 50000
    # points lists the valid cells return by return, ring by ring, in column order.
    ret, ring, col = np.nonzero(valid)
    assert np.array_equal(points["ring"], ring) and np.array_equal(points["column"], col)
    for name in ("x", "y", "z", "range", "azimuth", "time", "intensity", "return_type"):
        assert np.array_equal(points[name], arrays[name][valid]), name
    np.testing.assert_allclose(np.sqrt(points["x"] ** 2 + points["y"] ** 2 + points["z"] ** 2),
                               points["range"], atol=0.02)
    assert np.all(arrays["range"][~valid] == 0)
    assert np.all((points["azimuth"] >= 0) & (points["azimuth"] < 360))
    assert np.all(np.diff(arrays["column_time"]) > 0)
    assert 0.099 < arrays["column_time"][-1] < 0.101  # one rotation at 600 rpm
    assert sorted(arrays["laser_id"].tolist()) == list(range(32))


def test_reading_is_lazy(demo):
    reader = lidartag.read(demo)
    assert iter(reader) is reader
    assert reader.counts["rotations"] == 0
    first = next(reader)
    assert reader.counts["rotations"] == 1 and reader.model == "vlp32c"
    packets_after_one = reader.counts["data_packets"]
    rest = list(reader)
    assert len(rest) == 9
    assert reader.counts["data_packets"] > 5 * packets_after_one
    assert reader.counts["decode_errors"] == 0
    assert reader.counts["skipped_incomplete"] == 2
    assert reader.model_mismatch == ""
    assert first.sequence < rest[0].sequence
    with pytest.raises(StopIteration):
        next(reader)


def test_read_options(demo, tmp_path):
    by_name = next(iter(lidartag.read(demo, model="VLP32C")))  # case does not matter
    assert by_name.model == "vlp32c"
    cut = next(iter(lidartag.read(demo, cut_deg=90.0)))
    assert abs(cut.arrays()["column_azimuth"][0] - 90.0) < 0.5
    assert cut.complete
    # Other ports: no sensor packets at all.
    # Nothing on those ports: an error naming the counts, as `lidartag` says it (issue 36).
    with pytest.raises(lidartag.IoError, match="no rotation: 0 data packets"):
        list(lidartag.read(demo, data_port=2369, position_port=8309))
    with pytest.raises(ValueError, match="unknown model 'hdl64'"):
        lidartag.read(demo, model="hdl64")
    with pytest.raises(lidartag.IoError):
        lidartag.read(tmp_path / "missing.pcap")
    bad = tmp_path / "bad.yaml"
    bad.write_text("lasers: []\n")
    with pytest.raises(lidartag.CalibrationError, match="bad.yaml"):
        lidartag.read(demo, model="vlp32c", calibration=bad)
    with pytest.raises(lidartag.Error):  # every setup error is a lidartag.Error
        lidartag.read(demo, model="vlp32c", calibration=bad)


@pytest.mark.parametrize("fmt", ["ascii", "binary", "binary_compressed"])
@pytest.mark.parametrize("organized", [False, True])
def test_pcd_files_round_trip(demo_rotations, tmp_path, fmt, organized):
    rotation = demo_rotations[2]
    path = tmp_path / "scan.pcd"
    assert lidartag.write_pcd(rotation, path, fmt, organized) == len(rotation)
    cloud = lidartag.read_pcd(path)
    assert cloud["format"] == fmt
    assert cloud["stamp_ns"] == rotation.stamp_ns
    assert cloud["sequence"] == rotation.sequence
    assert cloud["model"] == "vlp32c"
    assert set(cloud["fields"]) == {"x", "y", "z", "intensity", "ring", "azimuth", "time",
                                    "return_type"}
    if organized:
        assert (cloud["height"], cloud["width"]) == (32, rotation.columns)
        assert cloud["fields"]["x"].shape == (32, rotation.columns)
    back = next(iter(lidartag.read(path)))
    assert back.stamp_ns == rotation.stamp_ns and back.sequence == rotation.sequence
    assert back.model == "vlp32c" and back.return_mode == "strongest" and back.complete
    if organized:
        # Organised: every cell where it was.
        a, b = rotation.arrays(), back.arrays()
        assert np.array_equal(a["valid"], b["valid"])
        for name in ("x", "y", "z", "intensity", "azimuth", "time"):
            assert np.array_equal(a[name][a["valid"]], b[name][b["valid"]]), name
    else:
        # Unorganised: binned by azimuth (a few neighbours share a 0.2 degree column).
        assert 0.98 * len(rotation) < len(back) <= len(rotation)


def test_an_xyz_only_pcd_is_a_clear_error(tmp_path):
    path = tmp_path / "xyz.pcd"
    path.write_text("FIELDS x y z ring\nSIZE 4 4 4 2\nTYPE F F F U\nWIDTH 2\nDATA ascii\n"
                    "1 2 3 0\n4 5 6 1\n")
    assert set(lidartag.read_pcd(path)["fields"]) == {"x", "y", "z", "ring"}  # a valid PCD
    with pytest.raises(lidartag.CloudError, match="no intensity field"):
        lidartag.read(path)
    broken = tmp_path / "broken.pcd"
    broken.write_bytes(b"FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 9\nDATA binary\n\0\0")
    with pytest.raises(lidartag.IoError, match="cannot fit"):
        lidartag.read_pcd(broken)


def test_a_capture_without_a_rotation_is_an_error_as_in_the_cli(demo, tmp_path):
    # Issue 36: Python read a truncated pcap as 0 rotations without a word while `lidartag`
    # exited 1. The first 20 kB of the demo hold no complete rotation.
    cut = tmp_path / "cut.pcap"
    cut.write_bytes(open(demo, "rb").read()[:20000])
    with pytest.raises(lidartag.IoError, match="no complete rotation"):
        list(lidartag.read(cut))
    assert len(list(lidartag.read(cut, partial=True))) >= 1
    # A capture cut short by a corrupt record in the middle: every rotation before it, then the
    # error naming the record (the CLI's exit status 3).
    data = bytearray(open(demo, "rb").read())
    at = 24
    for _ in range(999):
        at += 16 + int.from_bytes(data[at + 8:at + 12], "little")
    data[at + 8:at + 12] = (1 << 20).to_bytes(4, "little")
    corrupt = tmp_path / "corrupt.pcap"
    corrupt.write_bytes(bytes(data))
    got = []
    with pytest.raises(lidartag.IoError, match="unreadable after record 999"):
        for rotation in lidartag.read(corrupt):
            got.append(rotation)
    assert len(got) >= 4
