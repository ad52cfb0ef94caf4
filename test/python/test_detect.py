"""The detector with the options of lidartagd's YAML, its detections with numpy poses."""
import json

import numpy as np
import pytest

import lidartag
from conftest import DEMO_CONFIG, DEMO_SIZES, expect_matches_truth


def test_detections_of_the_demo_match_its_truth(demo_rotations, truth):
    detector = lidartag.Detector(DEMO_SIZES)
    assert detector.tag_sizes_m == [0.8, 0.6] and detector.families == ["tag16h5"]
    for rotation, expected in zip(demo_rotations, truth["rotations"]):
        result = detector.detect(rotation)
        assert result.stamp_ns == rotation.stamp_ns and result.sequence == rotation.sequence
        expect_matches_truth(result, expected)
        for d in result:
            tag = next(t for t in expected["tags"] if t["id"] == d.id)
            assert d.size_m == tag["size"]
            q = np.asarray(tag["orientation"])
            assert abs(np.dot(q, d.orientation)) > np.cos(np.radians(3.0) / 2)
        assert result.features > 0 and result.clusters >= len(result)
        assert set(result.timing_ms) == {"features", "clustering", "validation", "plane",
                                         "corners", "pose", "decode"}
        assert result.total_ms == pytest.approx(sum(result.timing_ms.values()))


def test_python_and_the_cli_name_and_number_things_alike(demo, demo_rotations, lidartag_cli):
    # One name per thing: a rotation is its sequence number, lengths are *_m, in the CLI's JSON as
    # in Python (and LCM); the same rotation gives the same values under the same names.
    import subprocess
    out = subprocess.run([lidartag_cli, "detect", str(demo), "--tag-size", "0.8", "--tag-size",
                          "0.6", "--json", "--clusters", "--no-tracker"],
                         check=True, capture_output=True, text=True).stdout
    lines = [json.loads(line) for line in out.splitlines()]
    detector = lidartag.Detector(DEMO_SIZES, diagnostics=True)
    complete = [r for r in demo_rotations if r.complete]
    assert [j["sequence"] for j in lines] == [r.sequence for r in complete]
    assert lines[0]["sequence"] == 1  # rotation 0 is the capture's leading partial one
    cli, rotation = lines[0], complete[0]
    assert repr(rotation).startswith(f"<lidartag.Rotation {rotation.sequence} ")
    result = detector.detect(rotation)
    assert result.sequence == cli["sequence"]
    assert len(result) == len(cli["detections"]) == 2
    for j in cli["detections"]:
        d = next(d for d in result if d.id == j["id"])
        for key, value in j.items():
            assert hasattr(d, key), f"the CLI's detection key '{key}' is not a Detection attribute"
            if isinstance(value, (int, float, str)):
                assert getattr(d, key) == pytest.approx(value), key
    diagnostics = result.diagnostics
    for j in cli["cluster_diagnostics"]:
        d = diagnostics[j["index"]]
        for key in ("features", "points", "boundary_points", "outlier_ratio", "side_m",
                    "mean_cost_m", "coverage", "score", "margin"):
            if key in j:
                assert key in d, f"the CLI's cluster key '{key}' is not in Python's diagnostics"
                assert d[key] == pytest.approx(j[key], rel=1e-6, abs=1e-9), key
        # "lacked" is the CLI's sentence about what a sparse cluster lacked (from these numbers).
        cli_only = {"index", "result", "stage", "box", "rings", "lacked"}
        assert set(j) - cli_only <= set(d), set(j) - set(d)


def test_a_detection_is_a_consistent_pose(demo_rotations):
    result = lidartag.Detector(DEMO_SIZES).detect(demo_rotations[0])
    assert len(result) == 2
    for d in result:
        assert d.position.shape == (3,) and d.orientation.shape == (4,)
        assert d.rotation.shape == (3, 3) and d.pose.shape == (4, 4) and d.corners.shape == (4, 3)
        np.testing.assert_allclose(d.rotation @ d.rotation.T, np.eye(3), atol=1e-9)
        w, x, y, z = d.orientation
        from_quaternion = np.array([
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
        np.testing.assert_allclose(d.rotation, from_quaternion, atol=1e-9)
        np.testing.assert_array_equal(d.pose[:3, :3], d.rotation)
        np.testing.assert_array_equal(d.pose[:3, 3], d.position)
        np.testing.assert_allclose(d.corners.mean(axis=0), d.position, atol=1e-6)
        # The black square is 0.75 of the marker (16-bit families: 6 of 8 cells).
        side = np.linalg.norm(d.corners[1] - d.corners[0])
        assert side == pytest.approx(0.75 * d.size_m, rel=1e-6)
        with pytest.raises(ValueError):  # read-only
            d.position[0] = 0.0


def positions(detector, rotation):
    return sorted((d.id, *np.round(d.position, 9)) for d in detector.detect(rotation))


def test_every_form_of_the_config_gives_the_same_options(demo_rotations, tmp_path):
    rotation = demo_rotations[3]
    expected = positions(lidartag.Detector(DEMO_SIZES), rotation)
    assert len(expected) == 2
    text = "detector:\n  tag_sizes_m: [0.8, 0.6]\n  families: [tag16h5]\n"
    path = tmp_path / "config.yaml"
    path.write_text(text)
    for config in ({"detector": DEMO_SIZES}, text, str(path), path, DEMO_CONFIG,
                   {"tag_sizes_m": np.array([0.8, 0.6]), "families": ("tag16h5",)}):
        assert positions(lidartag.Detector(config), rotation) == expected, config
    # The defaults are the YAML's (a 1.2 m tag16h5): the demo's smaller tags are not found.
    assert positions(lidartag.Detector(), rotation) == []


def test_bad_configs_name_the_key(tmp_path):
    with pytest.raises(lidartag.ConfigError, match="detector.features.zeta"):
        lidartag.Detector({"features": {"zeta": 0.5}})
    with pytest.raises(lidartag.ConfigError, match="detector.tag_sizes_m"):
        lidartag.Detector("detector:\n  tag_sizes_m: [-1]\n")
    with pytest.raises(lidartag.ConfigError, match="YAML"):
        lidartag.Detector("detector: [unclosed\n")
    with pytest.raises(lidartag.ConfigError):
        lidartag.Detector({"families": ["tag99h9"]})
    with pytest.raises(TypeError):
        lidartag.Detector({"tag_sizes_m": [object()]})
    with pytest.raises(TypeError):
        lidartag.Detector(42)


def test_diagnostics_explain_every_cluster(demo_rotations):
    result = lidartag.Detector(DEMO_SIZES, diagnostics=True).detect(demo_rotations[0])
    assert len(result.diagnostics) == result.clusters
    results = [c["result"] for c in result.diagnostics]
    assert results.count("decode/accepted") == len(result) == 2
    for c in result.diagnostics:
        assert c["features"] >= 0 and c["min_ring"] <= c["max_ring"]
        if c["result"] == "decode/accepted":
            assert c["score"] > 0.9 and c["side_m"] > 0 and c["coverage"] > 0
    assert lidartag.Detector(DEMO_SIZES).detect(demo_rotations[0]).diagnostics == []


def test_detect_over_a_capture(demo, truth):
    results = list(lidartag.detect(demo, DEMO_SIZES))
    assert len(results) == 10
    for (rotation, result), expected in zip(results, truth["rotations"]):
        expect_matches_truth(result, expected)
    detector = lidartag.Detector(DEMO_SIZES)
    assert len(list(lidartag.detect(demo, detector, partial=True))) == 12


def test_a_point_cloud_from_anywhere_is_detected(demo_rotations, truth):
    # Rotation.points round-trips through Rotation.from_points: the same tags where the truth says.
    detector = lidartag.Detector(DEMO_SIZES)
    complete = [r for r in demo_rotations if r.complete]
    rotation, expected = complete[0], truth["rotations"][0]
    rebuilt = lidartag.Rotation.from_points(rotation.points, stamp_ns=rotation.stamp_ns,
                                            sequence=rotation.sequence)
    assert rebuilt.sequence == rotation.sequence and rebuilt.stamp_ns == rotation.stamp_ns
    assert rebuilt.rings == 32 and len(rebuilt) > 0.98 * len(rotation)
    expect_matches_truth(detector.detect(rebuilt), expected)
    # Detector.detect takes the array itself.
    expect_matches_truth(detector.detect(rotation.points), expected)


def test_a_cloud_without_rings_takes_them_from_the_model_or_fails_clearly(demo_rotations, truth):
    rotation = next(r for r in demo_rotations if r.complete)
    p = rotation.points
    # Another driver's cloud: plain float64 arrays, no ring, intensity scaled to 0-1.
    cloud = {"x": p["x"].astype(np.float64), "y": p["y"].astype(np.float64),
             "z": p["z"].astype(np.float64), "intensity": p["intensity"] / 255.0}
    result = lidartag.Detector(DEMO_SIZES).detect(cloud, model="vlp32c")
    expect_matches_truth(result, truth["rotations"][0])
    assert lidartag.Rotation.from_points(cloud, model="VLP-32C").model == "vlp32c"
    with pytest.raises(lidartag.CloudError, match="intensity"):
        lidartag.Rotation.from_points({k: cloud[k] for k in ("x", "y", "z")}, model="vlp32c")
    with pytest.raises(lidartag.CloudError, match="values"):
        lidartag.Rotation.from_points(dict(cloud, intensity=cloud["intensity"][:-1]),
                                      model="vlp32c")
    with pytest.raises(TypeError, match="structured array"):
        lidartag.Rotation.from_points(np.zeros((10, 4)))
    with pytest.raises(ValueError, match="unknown model"):
        lidartag.Rotation.from_points(cloud, model="hdl-99")


def test_each_detection_carries_the_time_the_beams_crossed_it(demo_rotations, truth):
    # Within 0.5 ms of when the beams crossed the tag's true centre: the time of the column whose
    # azimuth is nearest the centre's (azimuth clockwise from +x); first <= centre <= last.
    detector = lidartag.Detector(DEMO_SIZES)
    complete = [r for r in demo_rotations if r.complete]
    checked = 0
    for rotation, expected in zip(complete, truth["rotations"]):
        grid = rotation.arrays()
        azimuths, times = grid["column_azimuth"], grid["column_time"]
        for d in detector.detect(rotation):
            tag = next(t for t in expected["tags"] if t["id"] == d.id)
            x, y = tag["position"][0], tag["position"][1]
            centre = np.degrees(np.arctan2(-y, x)) % 360.0
            off = np.abs((azimuths - centre + 180.0) % 360.0 - 180.0)
            crossed = times[int(np.argmin(off))]
            assert abs(d.time_center_s - crossed) < 0.5e-3, (d.id, d.time_center_s, crossed)
            assert d.time_first_s <= d.time_center_s <= d.time_last_s
            # A 0.6-0.8 m tag at 3.5-4 m spans 9-13 degrees: 2.5-3.6 ms at 600 rpm.
            assert 1e-3 < d.time_last_s - d.time_first_s < 10e-3
            checked += 1
    assert checked == 2 * len(complete)


def test_a_size_the_points_contradict_is_warned_about(demo_rotations):
    # The size check: the demo's 0.8 m tag given as 0.75 m measures 0.8 m and is warned about;
    # given its size, the measure agrees and nothing is warned about.
    wrong = lidartag.Detector({"tag_sizes_m": [0.75, 0.6], "families": ["tag16h5"]})
    right = lidartag.Detector(DEMO_SIZES)
    warned = 0
    for rotation in demo_rotations:
        if not rotation.complete:
            continue
        for d in wrong.detect(rotation):
            if d.id == 0:
                assert d.size_m == 0.75 and d.measured_size_m == pytest.approx(0.8, rel=0.02)
                assert d.size_warning and "SIZE: measures 0." in repr(d)
                warned += 1
        for d in right.detect(rotation):
            assert not d.size_warning
            assert d.measured_size_m == pytest.approx(d.size_m, rel=0.02)
    assert warned == 10
