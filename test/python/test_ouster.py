"""lidartag.read on Ouster captures: real pcaps with their metadata and a ROS 1 bag of Ouster
packets (../shared/captures; skipped when absent), and simulated OS1-64 / OS1-128 captures that
`lidartag sim` writes with a tag, read and detected."""
import math
import subprocess

import numpy as np
import pytest

import lidartag
from conftest import SOURCE_DIR, expect_matches_truth

CAPTURES = SOURCE_DIR.parent / "shared" / "captures"
OUSTER = CAPTURES / "ouster" / "pcaps"

# The README's table: capture, metadata, model, lidar packets, IMU packets, frames (whole when
# every packet came), rings, returns.
REAL = [
    ("OS-1-32-G_v2.1.1_1024x10", None, "os1-32", 64, 0, 1, 32, 1),
    ("OS-2-32-U0_v2.0.0_1024x10", None, "os2-32", 64, 0, 1, 32, 1),
    ("OS-0-32-U1_v2.2.0_1024x10", None, "os0-32", 64, 10, 1, 32, 2),
    ("OS-0-128-U1_v2.3.0_1024x10", None, "os0-128", 64, 10, 1, 128, 1),
    ("OS-2-128-U1_v2.3.0_1024x10", None, "os2-128", 64, 10, 1, 128, 1),
    ("OS-1-128_v2.3.0_1024x10_lb_n3", "OS-1-128_v2.3.0_1024x10", "os1-128", 192, 30, 3, 128, 1),
]


def real(name):
    path = OUSTER / (name + ".pcap")
    if not path.exists():
        pytest.skip(f"no Ouster captures in {OUSTER}")
    return path


def expect_rings_by_elevation(rotation, altitudes_deg):
    """Ring 0 the lowest beam: the metadata's beam altitudes in ring order (laser_id is the beam's
    row in the sensor) never go down, and the returns' elevations rise from the lowest rings to
    the highest."""
    a = rotation.arrays()
    beams = a["laser_id"]
    assert sorted(beams) == list(range(rotation.rings))
    assert np.all(np.diff(np.asarray(altitudes_deg)[beams]) >= 0)
    valid = a["valid"][0]
    elevation = np.degrees(np.arctan2(a["z"][0], np.hypot(a["x"][0], a["y"][0])))
    quarter = rotation.rings // 4
    low = elevation[:quarter][valid[:quarter]]
    high = elevation[-quarter:][valid[-quarter:]]
    assert len(low) and len(high) and np.median(low) < np.median(high)


@pytest.mark.parametrize("name,metadata,model,lidar,imu,frames,rings,returns", REAL)
def test_real_ouster_pcaps_read_as_their_frames(name, metadata, model, lidar, imu, frames, rings,
                                                returns):
    pcap = real(name)
    meta = None if metadata is None else OUSTER / (metadata + ".json")
    reader = lidartag.read(pcap, metadata=meta)  # NAME.json beside NAME.pcap when not given
    rotations = list(reader)
    assert reader.vendor == "ouster" and reader.model == model
    assert len(rotations) == frames
    counts = reader.counts
    assert counts["data_packets"] == counts["decoded"] == lidar
    assert counts["imu_packets"] == imu
    assert counts["decode_errors"] == 0 and reader.model_mismatch == ""
    info = reader.sensor_info
    assert info["model"] == model and info["pixels_per_column"] == rings
    assert info["lidar_mode"] == "1024x10" or name.startswith("OS-2-32")  # its JSON: 1024x20
    for r in rotations:
        assert r.complete and r.model == model and r.return_mode == info["profile"]
        assert (r.rings, r.columns, r.returns) == (rings, 1024, returns)
        assert r.packets == 64
        # Ring 0 the lowest beam, rings ordered by elevation.
        expect_rings_by_elevation(r, info["beam_altitude_deg"])
        # Times within the frame's 100 ms, from its first column.
        points = r.points
        assert 0 <= points["time"].min() < 0.001 and points["time"].max() < 0.1
    # None of them holds a tag.
    detector = lidartag.Detector()
    assert all(len(detector.detect(r)) == 0 for r in rotations)


def test_a_part_of_a_frame_is_read_only_with_partial():
    # The FUSA dual capture holds 8 packets (128 columns) of one frame.
    pcap = real("OS-1-128_767798045_1024x10_20230712_120049")
    with pytest.raises(lidartag.IoError, match="no complete rotation"):
        list(lidartag.read(pcap))
    reader = lidartag.read(pcap, partial=True)
    (frame,) = list(reader)
    assert not frame.complete and frame.packets == 8 and frame.returns == 2
    assert frame.return_mode == "FUSA_RNG15_RFL8_NIR8_DUAL"
    assert reader.counts["decoded"] == 8 and reader.counts["imu_packets"] == 2


def test_an_ouster_pcap_without_its_metadata_says_so(tmp_path):
    alone = tmp_path / "alone.pcap"
    alone.write_bytes(real("OS-2-128-U1_v2.3.0_1024x10").read_bytes())
    with pytest.raises(lidartag.IoError, match=r"0 data packets.*74 packets to other ports: an "
                                               r"Ouster capture is read with its metadata"):
        list(lidartag.read(alone))


def test_real_ouster_metadata_given_and_found_beside_agree():
    pcap = real("OS-2-128-U1_v2.3.0_1024x10")
    beside = next(iter(lidartag.read(pcap)))
    given = next(iter(lidartag.read(pcap, metadata=OUSTER / "OS-2-128-U1_v2.3.0_1024x10.json",
                                    model="OS2-128")))
    assert np.array_equal(beside.points, given.points)


def test_signal_intensity_is_an_option():
    pcap = real("OS-2-128-U1_v2.3.0_1024x10")
    reflectivity = next(iter(lidartag.read(pcap))).arrays()
    signal = next(iter(lidartag.read(pcap, intensity="signal"))).arrays()
    assert np.array_equal(reflectivity["valid"], signal["valid"])
    assert np.array_equal(reflectivity["range"], signal["range"])
    assert not np.array_equal(reflectivity["intensity"], signal["intensity"])
    # LEGACY carries SIGNAL too.
    legacy = real("OS-1-32-G_v2.1.1_1024x10")
    assert not np.array_equal(next(iter(lidartag.read(legacy, intensity="signal"))).points,
                              next(iter(lidartag.read(legacy))).points)
    # RNG15 carries no SIGNAL: refused, as the C++ decoder refuses it.
    with pytest.raises(ValueError, match="(?i)signal"):
        lidartag.read(real("OS-0-128-U1_v2.3.0_1024x10"), intensity="signal")
    with pytest.raises(ValueError, match="reflectivity or signal"):
        lidartag.read(real("OS-2-128-U1_v2.3.0_1024x10"), intensity="nir")


def test_wrong_metadata_and_wrong_model_are_metadata_errors():
    pcap = real("OS-2-128-U1_v2.3.0_1024x10")
    # Metadata of another sensor (32 beams, another packet size): refused at the end, naming it.
    with pytest.raises(lidartag.MetadataError, match="does not describe"):
        list(lidartag.read(pcap, metadata=OUSTER / "OS-1-32-G_v2.1.1_1024x10.json"))
    with pytest.raises(lidartag.MetadataError, match="os1-64"):
        lidartag.read(pcap, model="os1-64")
    malformed = sorted((CAPTURES / "ouster" / "metadata" / "malformed").glob("*.json"))
    assert malformed
    for path in malformed:
        with pytest.raises(lidartag.MetadataError):
            lidartag.read(pcap, metadata=path)
    # A Velodyne model or calibration with Ouster metadata is a contradiction.
    with pytest.raises(ValueError, match="Ouster packets"):
        lidartag.read(pcap, model="vlp32c", metadata=OUSTER / "OS-2-128-U1_v2.3.0_1024x10.json")


def test_an_ouster_ros1_bag_reads_its_frame_with_the_metadata_topic():
    bag = CAPTURES / "bags" / "ros1" / "ouster_os0-128_512x10_packets.bag"
    if not bag.exists():
        pytest.skip(f"no bags in {CAPTURES / 'bags'}")
    reader = lidartag.read(bag)
    rotations = list(reader)
    assert reader.vendor == "ouster" and reader.model == "os0-128"
    assert "metadata" in reader.source and "/os_node0/lidar_packets" in reader.source
    assert reader.sensor_info["lidar_mode"] == "512x10"
    assert reader.counts["data_packets"] == reader.counts["decoded"] == 32
    assert reader.counts["imu_packets"] == 10
    assert len(rotations) == 1
    r = rotations[0]
    assert r.complete and (r.rings, r.columns) == (128, 512)
    assert r.return_mode == "RNG15_RFL8_NIR8"
    expect_rings_by_elevation(r, reader.sensor_info["beam_altitude_deg"])
    assert len(lidartag.Detector().detect(r)) == 0
    # A time window over the bag's messages: one that holds them all gives the same frame; one
    # after the bag's end none, its 43 messages (32 lidar, 10 IMU, the metadata) counted outside
    # it, as `lidartag info --start 1000` counts them.
    whole = list(lidartag.read(bag, start=0.0, duration=1000.0))
    assert len(whole) == 1 and np.array_equal(whole[0].points, r.points)
    window = lidartag.read(bag, start=1000.0, partial=True)
    with pytest.raises(lidartag.IoError, match="no rotation"):
        list(window)
    assert window.counts["outside_window"] == 43


def test_velodyne_reads_keep_their_counts_and_refuse_ouster_options(demo):
    reader = lidartag.read(demo)
    assert reader.vendor == "velodyne" and reader.sensor_info is None
    assert len(list(reader)) == 10 and reader.counts["position_packets"] == 0
    with pytest.raises(ValueError, match="Ouster"):
        lidartag.read(demo, intensity="signal")


SCENE = """
sensor: {{model: {model}, lidar_mode: 1024x10, profile: {profile}, height: 1.0}}
tags:
  - {{family: tag16h5, id: 3, size: 1.2, center: [5.0, 0.3, 1.1], rotation: 45, stand: true}}
rotations: 3
"""


@pytest.mark.parametrize("model,profile,rings", [("os1-64", "rng19", 64),
                                                 ("os1-128", "legacy", 128)])
def test_a_simulated_ouster_capture_is_read_and_its_tag_detected(lidartag_cli, tmp_path, model,
                                                                 profile, rings):
    import json
    scene = tmp_path / "scene.yaml"
    scene.write_text(SCENE.format(model=model, profile=profile))
    pcap, truth_path = tmp_path / "sim.pcap", tmp_path / "sim.truth.json"
    subprocess.run([lidartag_cli, "sim", str(scene), "--out", str(pcap), "--truth",
                    str(truth_path)], check=True, capture_output=True)
    assert (tmp_path / "sim.json").exists()  # the metadata, beside the capture
    truth = json.loads(truth_path.read_text())
    reader = lidartag.read(pcap)
    rotations = list(reader)
    assert reader.vendor == "ouster" and reader.model == model
    assert len(rotations) == len(truth["rotations"]) == 3
    detector = lidartag.Detector({"tag_sizes_m": [1.2], "families": ["tag16h5"]})
    for rotation, expected in zip(rotations, truth["rotations"]):
        assert rotation.complete and rotation.rings == rings and rotation.model == model
        assert abs(rotation.stamp_ns - expected["stamp_ns"]) < 1000
        expect_matches_truth(detector.detect(rotation), expected)
    # lidartag.detect takes the same options.
    found = [len(result) for _, result in lidartag.detect(pcap, detector, metadata=tmp_path /
                                                         "sim.json")]
    assert found == [1, 1, 1]
    # The reflectivity scale: the tag's white is diffuse (0-100 of 255).
    assert 0 < rotations[0].points["intensity"].max() <= 255
    assert math.isfinite(float(rotations[0].points["x"].mean()))


def test_simulate_writes_an_ouster_capture_with_its_metadata_or_decodes_it_in_memory(tmp_path):
    scene = SCENE.format(model="os1-64", profile="rng19")
    rotations, truth = lidartag.simulate(scene)
    assert len(rotations) == len(truth["rotations"]) == 3
    detector = lidartag.Detector({"tag_sizes_m": [1.2], "families": ["tag16h5"]})
    for rotation, expected in zip(rotations, truth["rotations"]):
        assert rotation.model == "os1-64" and rotation.rings == 64 and rotation.complete
        assert rotation.return_mode == "RNG19_RFL8_SIG16_NIR16"
        expect_matches_truth(detector.detect(rotation), expected)
    # Written: NAME.pcap and its metadata NAME.json, read back as the rotations in memory.
    pcap = tmp_path / "os1.pcap"
    written = lidartag.simulate(scene, out=pcap)
    assert written["rotations"] == truth["rotations"]
    reader = lidartag.read(pcap)
    assert reader.source == "pcap, metadata " + str(tmp_path / "os1.json")
    for a, b in zip(reader, rotations):
        assert a.stamp_ns == b.stamp_ns and np.array_equal(a.points, b.points)
    with pytest.raises(ValueError, match="metadata goes"):
        lidartag.simulate(scene, out=tmp_path / "os1.json")


def test_an_ouster_cloud_without_rings_takes_them_from_the_ouster_model(demo):
    # Another driver's OS1-64 cloud (no ring field): model="os1-64" places its rings from the
    # model's beam table; the tag is found where the rotation itself shows it.
    rotations, truth = lidartag.simulate(SCENE.format(model="os1-64", profile="rng19"))
    rotation, expected = rotations[0], truth["rotations"][0]
    p = rotation.points
    cloud = {k: p[k].astype(np.float64) for k in ("x", "y", "z", "intensity")}
    detector = lidartag.Detector({"tag_sizes_m": [1.2], "families": ["tag16h5"]})
    rebuilt = lidartag.Rotation.from_points(cloud, model="OS1-64")
    assert rebuilt.rings == 64 and len(rebuilt) > 0.95 * len(rotation)  # a few share a cell
    expect_matches_truth(detector.detect(rebuilt), expected)
    expect_matches_truth(detector.detect(cloud, model="os1-64"), expected)
    with pytest.raises(lidartag.CloudError, match="no ring field"):
        lidartag.Rotation.from_points(cloud)
    # An Ouster model for a capture without Ouster metadata: refused, not read as Velodyne.
    with pytest.raises(ValueError, match="has no Ouster metadata"):
        lidartag.read(demo, model="os1-128")
