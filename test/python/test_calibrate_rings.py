"""The ring-spacing term of `lidartag calibrate` from Python (issue 30): ring_spacing_covariance,
detection_covariance, calibrate(ring_elevations=...), and Python giving the extrinsic the CLI gives
on the same simulated images and captures."""
import json
import math
import subprocess

import numpy as np
import pytest

import lidartag

VLP16_DEG = np.arange(-15.0, 16.0, 2.0)  # the VLP-16's 16 beams, 2 degrees apart


def square_tag(centre, h):
    """Corners (calibrate's order) of a tag facing the sensor from +x, edges along the rings:
    tag frame x (its normal) = -x, z up, y = z cross x = -y."""
    cx, cy, cz = centre
    return np.array([[cx, cy + h, cz - h], [cx, cy - h, cz - h], [cx, cy - h, cz + h],
                     [cx, cy + h, cz + h]])


def diamond_tag(centre, h):
    """The same tag turned 45 degrees in its plane."""
    square = square_tag(centre, h) - np.asarray(centre)
    c, s = math.cos(math.pi / 4), math.sin(math.pi / 4)
    turn = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    return square @ turn.T + np.asarray(centre)


def test_a_square_tag_gets_the_gap_over_sqrt12_across_the_rings_and_a_diamond_none():
    h = 0.4  # a 1.0 m tag36h11: black square 0.8 m
    square = square_tag((5.0, 0.0, 0.0), h)
    cov = lidartag.ring_spacing_covariance(square, np.radians(VLP16_DEG))
    assert cov.shape == (12, 12)
    # The rings about the tag's elevation (0 deg) are 2 degrees apart: at 5 m a gap of
    # 5 * 2 * pi / 180 m, known to gap / sqrt(12), moving the four corners together vertically.
    sigma = 5.0 * math.radians(2.0) / math.sqrt(12)
    z = [3 * k + 2 for k in range(4)]
    assert np.allclose(cov[np.ix_(z, z)], sigma ** 2, rtol=1e-9)
    others = np.ones((12, 12), bool)
    others[np.ix_(z, z)] = False
    assert np.allclose(cov[others], 0.0, atol=1e-12)
    # A diamond's edges cross the rings: they locate it, no term.
    diamond = lidartag.ring_spacing_covariance(diamond_tag((5.0, 0.0, 0.0), h),
                                               np.radians(VLP16_DEG))
    assert np.allclose(diamond, 0.0, atol=1e-15)
    # Twice as far, twice the gap; one list of rings per pose, or a Rotation's rings.
    both = lidartag.ring_spacing_covariance(
        np.stack([square, square_tag((10.0, 0.0, 0.0), h)]),
        [np.radians(VLP16_DEG), np.radians(VLP16_DEG)])
    assert both.shape == (2, 12, 12)
    assert both[1][2, 2] == pytest.approx(4 * both[0][2, 2], rel=1e-9)
    with pytest.raises(ValueError, match=r"\(P, 4, 3\)"):
        lidartag.ring_spacing_covariance(np.zeros((2, 3, 3)), np.radians(VLP16_DEG))
    with pytest.raises(ValueError, match="radians"):
        lidartag.ring_spacing_covariance(square, VLP16_DEG)  # degrees by mistake


def test_detection_covariance_is_the_pose_noise_of_one_rotation():
    square = square_tag((5.0, 0.0, 0.0), 0.4)
    # No angle error: every corner moves with the position (3 mm) plus its own floor (2 mm).
    cov = lidartag.detection_covariance(square, position_sigma_m=0.003, angle_sigma_deg=0.0,
                                        floor_m=0.002)
    expected = np.kron(np.ones((4, 4)), np.eye(3) * 0.003 ** 2) + np.eye(12) * 0.002 ** 2
    assert np.allclose(cov, expected, atol=1e-15)
    # With an angle error the corners far from the centre move more than the centre's sigma.
    turned = lidartag.detection_covariance(square)
    assert np.all(np.diag(turned) >= np.diag(cov) - 1e-15)
    assert np.any(np.diag(turned) > np.diag(cov) + 1e-7)


def test_calibrate_adds_the_ring_term_when_given_the_rings():
    camera = lidartag.CameraModel(640, 360, 450, 450, 319.5, 179.5)
    # Three tags in front of a camera that looks along the LiDAR's +x.
    lidar = np.stack([square_tag((4.0, 0.5, 0.2), 0.4), diamond_tag((5.0, -0.8, -0.1), 0.4),
                      square_tag((6.0, 0.2, 0.5), 0.4)])
    cam_from_lidar = np.array([[0, -1, 0], [0, 0, -1], [1, 0, 0]], float)
    points = lidar.reshape(-1, 3) @ cam_from_lidar.T
    image = camera.project(points).reshape(3, 4, 2)
    rings = np.radians(VLP16_DEG)
    cov = lidartag.detection_covariance(lidar)
    with_rings = lidartag.calibrate(camera, image, lidar, lidar_covariance=cov,
                                    ring_elevations=rings)
    by_hand = lidartag.calibrate(camera, image, lidar,
                                 lidar_covariance=cov + lidartag.ring_spacing_covariance(lidar,
                                                                                         rings))
    without = lidartag.calibrate(camera, image, lidar, lidar_covariance=cov)
    assert np.array_equal(with_rings.camera_from_lidar, by_hand.camera_from_lidar)
    assert with_rings.sigma["translation_mm"] == by_hand.sigma["translation_mm"]
    # The square tags' vertical uncertainty widens the result's.
    assert with_rings.sigma["rotation_total_deg"] > without.sigma["rotation_total_deg"]
    assert np.allclose(with_rings.camera_from_lidar[:3, :3], cam_from_lidar, atol=1e-6)


# The scene of test/tools/cli_calibrate_test.cpp, one rotation per pose (the CLI then takes each
# capture's detections, as Python does below).
SCENE = """
sensor: {model: vlp32c, height: 1.0}
world: {room: {center: [4, 0], size: [16, 10], height: 3.2}}
camera: {width: 640, height: 360, fx: 450, distortion_model: plumb_bob,
  distortion_coefficients: [-0.12, 0.06, 0.0008, -0.0005, 0.0],
  rotation_wxyz: [0.481240400, 0.500957013, -0.511747708, 0.505533414],
  translation_m: [0.1, -0.05, -0.08]}
rotations: 1
tags:
  - {family: tag36h11, id: 5, size: 1.0, center: [4.0, 0.3, 1.2]}
series:
  - {center: [3.0, 0.9, 1.3], normal: [-1, 0.2, 0], rotation: square}
  - {center: [3.5, -1.0, 0.9], normal: [-1, -0.3, 0.1], rotation: 30}
  - {center: [5.0, 0.0, 1.6], normal: [-1, 0, -0.2], rotation: diamond}
  - {center: [6.0, -1.8, 1.4], normal: [-1, -0.2, 0.2], rotation: 20}
  - {center: [4.2, 0.3, 0.7], normal: [-1, 0.1, 0.3], rotation: diamond}
  - {center: [4.8, 1.3, 1.5], normal: [-1, 0.3, -0.3], rotation: 40}
"""
CAMERA = """image_width: 640
image_height: 360
camera_name: sim
camera_matrix: {rows: 3, cols: 3, data: [450, 0, 319.5, 0, 450, 179.5, 0, 0, 1]}
distortion_model: plumb_bob
distortion_coefficients: {rows: 1, cols: 5, data: [-0.12, 0.06, 0.0008, -0.0005, 0.0]}
"""


def test_python_gives_the_extrinsic_of_lidartag_calibrate(lidartag_cli, tmp_path):
    (tmp_path / "calib.yaml").write_text(SCENE)
    (tmp_path / "camera.yaml").write_text(CAMERA)
    subprocess.run([lidartag_cli, "sim", str(tmp_path / "calib.yaml"), "--out",
                    str(tmp_path / "cal.pcap")], check=True, capture_output=True)
    names = ["cal_%02d" % i for i in range(6)]
    pairs = []
    for n in names:
        pairs += ["--pair", str(tmp_path / (n + ".png")), str(tmp_path / (n + ".pcap"))]
    cli = subprocess.run([lidartag_cli, "calibrate", "--camera", str(tmp_path / "camera.yaml"),
                          *pairs, "--family", "tag36h11", "--tag-size", "1.0", "--json"],
                         check=True, capture_output=True, text=True)
    expected = json.loads(cli.stdout)

    # The same in Python: the capture's one rotation detected, the image's tags, paired by ID.
    camera = lidartag.load_intrinsics(tmp_path / "camera.yaml")
    detector = lidartag.Detector({"families": ["tag36h11"], "tag_sizes_m": [1.0]})
    image, lidar, rotations = [], [], []
    for n in names:
        (rotation,) = list(lidartag.read(tmp_path / (n + ".pcap")))
        found = {(d.family, d.id): d for d in detector.detect(rotation)}
        for tag in lidartag.detect_image_tags(tmp_path / (n + ".png"), ["tag36h11"], camera):
            d = found.get((tag["family"], tag["id"]))
            if d is not None:
                image.append(tag["corners"])
                lidar.append(np.asarray(d.corners))
                rotations.append(rotation)
    assert len(lidar) == expected["poses_used"] + len(expected["poses_rejected"])
    assert len(lidar) >= 5
    lidar = np.array(lidar)
    result = lidartag.calibrate(camera, np.array(image), lidar, sigma_px=0.3,
                                lidar_covariance=lidartag.detection_covariance(lidar),
                                ring_elevations=rotations)
    assert np.allclose(result.camera_from_lidar, np.array(expected["lidar_to_camera"]["matrix"]),
                       atol=1e-9)
    assert result.sigma["rotation_total_deg"] == pytest.approx(
        expected["lidar_to_camera"]["sigma"]["rotation_total_deg"], rel=1e-6)
    # Without the ring term the result is another one (a square-mounted pose is in the set).
    plain = lidartag.calibrate(camera, np.array(image), lidar, sigma_px=0.3,
                               lidar_covariance=lidartag.detection_covariance(lidar))
    assert plain.sigma["rotation_total_deg"] != pytest.approx(
        result.sigma["rotation_total_deg"], rel=1e-6)
