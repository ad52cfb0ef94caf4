"""lidartag.calibrate and its companions: camera models, intrinsics files, image tags.

The synthetic scene: a known camera-from-LiDAR extrinsic, 9 tags at 2-8 m facing the sensors with
tilts, their black squares' corners in the LiDAR frame (with 3 mm of noise) and projected through a
plumb-bob 1280x720 camera (with 0.3 px of noise)."""
import json

import numpy as np
import pytest

import lidartag
from conftest import SOURCE_DIR

CAMERA_INFO = """image_width: 1280
image_height: 720
camera_name: front
camera_matrix:
  rows: 3
  cols: 3
  data: [905.5, 0, 641.25, 0, 903.5, 358.75, 0, 0, 1]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [-0.12, 0.05, 0.0008, -0.0006, -0.01]
"""


def camera():
    return lidartag.CameraModel(1280, 720, 905.5, 903.5, 641.25, 358.75, "plumb_bob",
                                [-0.12, 0.05, 0.0008, -0.0006, -0.01])


def rotation(axis, angle_deg):
    """Rodrigues: the rotation by angle_deg about axis."""
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a)
    t = np.radians(angle_deg)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(t) * k + (1 - np.cos(t)) * k @ k


def true_extrinsic():
    """camera_from_lidar: LiDAR x forward, y left, z up into the optical frame (x right, y down,
    z forward), turned by a few degrees, the camera 12 cm below and 5 cm beside the LiDAR."""
    base = np.array([[0, -1, 0], [0, 0, -1], [1, 0, 0]], dtype=float)
    t = np.eye(4)
    t[:3, :3] = rotation([0.3, -0.5, 0.8], 3.0) @ base
    t[:3, 3] = [0.05, 0.12, -0.03]
    return t


def scene(rng, lidar_noise_m=0.003, pixel_noise=0.3):
    """(image_corners (9, 4, 2), lidar_corners (9, 4, 3), truth): 0.8 m tags (black square 0.6 m)
    at 2-8 m, each facing the sensor, tilted, corners as docs/calibration.md orders them."""
    cam = camera()
    truth = true_extrinsic()
    h = 0.3
    # Tag frame corners (x normal out of the front, y right, z up): k = 0 bottom-left, 1
    # bottom-right, 2 top-right, 3 top-left.
    local = np.array([[0, -h, -h], [0, h, -h], [0, h, h], [0, -h, h]])
    placements = [  # range m, azimuth deg (left +), elevation deg, yaw, pitch, roll tilt deg
        (2.0, 20, 5, 25, 10, 5), (2.5, -22, -6, -30, 5, -10), (3.0, 0, 8, 10, -20, 0),
        (3.5, 15, -8, -15, 15, 30), (4.5, -12, 4, 35, -10, -20), (5.0, 5, -3, -20, 25, 45),
        (6.0, -18, -5, 15, 0, 10), (7.0, 20, 6, -35, -15, -5), (8.0, -3, 0, 0, 20, 15)]
    image, lidar = [], []
    for r, az, el, yaw, pitch, roll in placements:
        a, e = np.radians(az), np.radians(el)
        centre = r * np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
        x = -centre / r
        z = np.array([0, 0, 1.0]) - x[2] * x
        z /= np.linalg.norm(z)
        face = np.column_stack([x, np.cross(z, x), z])  # tag frame -> LiDAR frame
        tilt = rotation([0, 0, 1], yaw) @ rotation([0, 1, 0], pitch) @ rotation([1, 0, 0], roll)
        corners = centre + local @ (face @ tilt).T
        in_camera = corners @ truth[:3, :3].T + truth[:3, 3]
        pixels = cam.project(in_camera)
        assert np.all(np.isfinite(pixels)), (r, az)
        assert np.all((pixels > 0) & (pixels < [1279, 719])), (r, az, pixels)
        image.append(pixels + rng.normal(0, pixel_noise, pixels.shape))
        lidar.append(corners + rng.normal(0, lidar_noise_m, corners.shape))
    return np.array(image), np.array(lidar), truth


def errors(estimate, truth):
    """(rotation error deg, translation error mm) of an estimated camera_from_lidar."""
    d = estimate[:3, :3] @ truth[:3, :3].T
    angle = np.degrees(np.arccos(np.clip((np.trace(d) - 1) / 2, -1, 1)))
    return angle, 1000 * np.linalg.norm(estimate[:3, 3] - truth[:3, 3])


def test_calibrate_recovers_a_known_extrinsic():
    image, lidar, truth = scene(np.random.default_rng(7))
    result = lidartag.calibrate(camera(), image, lidar, sigma_px=0.3, lidar_sigma_m=0.003)
    angle, shift = errors(result.camera_from_lidar, truth)
    print(f"\nrotation error {angle:.4f} deg, translation error {shift:.2f} mm, rms "
          f"{result.rms_px:.3f} px, held-out median {result.held_out_median_px:.3f} px, 1-sigma "
          f"{result.sigma['rotation_total_deg']:.4f} deg {result.sigma['translation_mm']} mm")
    assert angle < 0.1 and shift < 5.0
    assert result.camera_from_lidar.shape == (4, 4)
    np.testing.assert_allclose(result.camera_from_lidar @ result.lidar_from_camera, np.eye(4),
                               atol=1e-12)
    # The quaternion and translation are the matrix's.
    w, x, y, z = result.rotation_wxyz
    assert abs(np.linalg.norm(result.rotation_wxyz) - 1) < 1e-12 and w >= 0
    r = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                  [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                  [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    np.testing.assert_allclose(r, result.camera_from_lidar[:3, :3], atol=1e-12)
    np.testing.assert_allclose(result.translation_m, result.camera_from_lidar[:3, 3])
    # The errors and the 1-sigma fit the noise put in: 0.3 px per axis, and 3 mm per axis of the
    # LiDAR corners, 1.35 px at 2 m, 0.34 px at 8 m.
    assert 0.4 < result.rms_px < 1.5
    assert 0.4 < result.held_out_median_px < 2.5
    assert 0 < result.sigma["rotation_total_deg"] < 0.05
    assert all(0 < s < 3 for s in result.sigma["translation_mm"])
    assert result.sigma["covariance"].shape == (6, 6)
    assert result.poses_used == 9 and result.rejected == []
    assert [p["label"] for p in result.poses] == [f"pose {i}" for i in range(9)]
    assert all(p["used"] and len(p["corner_px"]) == 4 for p in result.poses)
    ranges = [p["range_m"] for p in result.poses]
    assert 1.8 < min(ranges) and max(ranges) < 8.3


def test_a_wrong_pose_is_rejected_with_its_reason():
    image, lidar, truth = scene(np.random.default_rng(8))
    # The tenth pose pairs the image of tag 0 with LiDAR corners 40 cm off (a moved tag).
    image = np.concatenate([image, image[:1]])
    lidar = np.concatenate([lidar, lidar[:1] + [0, 0.4, 0]])
    labels = [f"tag {i}" for i in range(9)] + ["moved"]
    result = lidartag.calibrate(camera(), image, lidar, sigma_px=0.3, lidar_sigma_m=0.003,
                                labels=labels)
    angle, shift = errors(result.camera_from_lidar, truth)
    assert angle < 0.1 and shift < 5.0
    assert result.poses_used == 9
    assert [r["label"] for r in result.rejected] == ["moved"]
    assert result.rejected[0]["reason"]
    assert not result.poses[9]["used"] and result.poses[9]["reason"]
    assert any("moved" in w or "reject" in w for w in result.warnings), result.warnings


def test_one_pose_solves_and_warns():
    image, lidar, truth = scene(np.random.default_rng(9))
    result = lidartag.calibrate(camera(), image[:1], lidar[:1], held_out=False)
    assert result.poses_used == 1
    assert result.warnings, "one pose must be warned about"
    assert result.held_out_median_px == -1


def test_to_json_has_the_keys_of_lidartag_calibrate():
    image, lidar, _ = scene(np.random.default_rng(10))
    result = lidartag.calibrate(camera(), image, lidar, held_out=False, lidar_frame="velodyne",
                                camera_frame="cam_optical")
    data = json.loads(result.to_json())
    assert data == result.json
    assert set(data) == {"lidar_to_camera", "errors", "poses", "poses_used", "poses_rejected",
                         "degeneracy", "warnings", "frames", "forms"}
    assert set(data["lidar_to_camera"]) >= {"rotation_wxyz", "translation_m", "matrix", "inverse",
                                            "sigma"}
    np.testing.assert_array_equal(np.array(data["lidar_to_camera"]["matrix"]),
                                  result.camera_from_lidar)
    assert data["frames"] == {"parent": "velodyne", "child": "cam_optical"}
    assert "velodyne" in result.forms["urdf"] and "cam_optical" in result.forms["ros2"]
    assert isinstance(result.suggestion, str) and isinstance(result.weak, list)


def test_per_pose_sigmas_and_covariances_are_taken():
    image, lidar, truth = scene(np.random.default_rng(11))
    cov = np.repeat((0.003 ** 2 * np.eye(12))[None], 9, axis=0)
    a = lidartag.calibrate(camera(), image, lidar, sigma_px=np.full(9, 0.3), lidar_covariance=cov,
                           held_out=False)
    b = lidartag.calibrate(camera(), image, lidar, sigma_px=0.3, lidar_sigma_m=0.003,
                           held_out=False)
    np.testing.assert_allclose(a.camera_from_lidar, b.camera_from_lidar, atol=1e-12)
    # A 10x looser LiDAR noise model gives a larger translation sigma.
    c = lidartag.calibrate(camera(), image, lidar, sigma_px=0.3, lidar_sigma_m=0.03,
                           held_out=False)
    assert c.sigma["translation_mm"][2] > b.sigma["translation_mm"][2]


@pytest.mark.parametrize("change, message", [
    (lambda i, l: (i[..., :1], l), "image_corners must be shaped"),
    (lambda i, l: (i[:, :3], l), "image_corners must be shaped"),
    (lambda i, l: (i, l[..., :2]), "lidar_corners must be shaped"),
    (lambda i, l: (i, l[:5]), "9 poses of image corners but 5"),
    (lambda i, l: (i[:0], l[:0]), "no pose"),
    (lambda i, l: (i[0], l[0]), "image_corners must be shaped"),
    (lambda i, l: (np.where(np.arange(72).reshape(9, 4, 2) == 17, np.nan, i), l),
     "image_corners of pose 2 is not finite"),
    (lambda i, l: (i, np.where(np.arange(108).reshape(9, 4, 3) == 50, np.inf, l)),
     "lidar_corners of pose 4 is not finite"),
])
def test_bad_arrays_raise_value_error(change, message):
    image, lidar, _ = scene(np.random.default_rng(12))
    image, lidar = change(image, lidar)
    with pytest.raises(ValueError, match=message):
        lidartag.calibrate(camera(), image, lidar)


def test_bad_options_raise_value_error():
    image, lidar, _ = scene(np.random.default_rng(13))
    cam = camera()
    with pytest.raises(ValueError, match="sigma_px"):
        lidartag.calibrate(cam, image, lidar, sigma_px=-1)
    with pytest.raises(ValueError, match="sigma_px"):
        lidartag.calibrate(cam, image, lidar, sigma_px=[0.3, 0.3])
    with pytest.raises(ValueError, match="lidar_sigma_m"):
        lidartag.calibrate(cam, image, lidar, lidar_sigma_m=np.nan)
    with pytest.raises(ValueError, match="lidar_covariance"):
        lidartag.calibrate(cam, image, lidar, lidar_covariance=np.zeros((9, 3, 3)))
    with pytest.raises(ValueError, match="3 labels for 9 poses"):
        lidartag.calibrate(cam, image, lidar, labels=["a", "b", "c"])
    with pytest.raises(TypeError, match="CameraModel"):
        lidartag.calibrate({"fx": 900}, image, lidar)
    with pytest.raises(ValueError):
        lidartag.calibrate(cam, "not an array", lidar)


def test_camera_model_from_numbers_and_project():
    cam = camera()
    assert (cam.width, cam.height, cam.fx, cam.fy, cam.cx, cam.cy) == (1280, 720, 905.5, 903.5,
                                                                        641.25, 358.75)
    assert cam.distortion == "plumb_bob"
    assert cam.coefficients == [-0.12, 0.05, 0.0008, -0.0006, -0.01]
    np.testing.assert_array_equal(cam.K, [[905.5, 0, 641.25], [0, 903.5, 358.75], [0, 0, 1]])
    pixels = cam.project([[0, 0, 2.0], [0.5, -0.2, 3.0], [0, 0, -1.0], [np.nan, 0, 1]])
    assert pixels.shape == (4, 2)
    np.testing.assert_allclose(pixels[0], [641.25, 358.75])
    # The plumb-bob model by hand.
    x, y = 0.5 / 3, -0.2 / 3
    r2 = x * x + y * y
    radial = 1 - 0.12 * r2 + 0.05 * r2 ** 2 - 0.01 * r2 ** 3
    xd = x * radial + 2 * 0.0008 * x * y - 0.0006 * (r2 + 2 * x * x)
    yd = y * radial + 0.0008 * (r2 + 2 * y * y) + 2 * -0.0006 * x * y
    np.testing.assert_allclose(pixels[1], [905.5 * xd + 641.25, 903.5 * yd + 358.75], atol=1e-9)
    assert np.all(np.isnan(pixels[2])) and np.all(np.isnan(pixels[3]))
    assert cam.project([0, 0, 1.0]).shape == (2,)
    pinhole = lidartag.CameraModel(640, 480, 500, 500, 320, 240)
    assert pinhole.distortion == "none" and pinhole.coefficients == []
    np.testing.assert_allclose(pinhole.project([[1.0, 0.5, 2.0]]), [[570, 365]])
    fisheye = lidartag.CameraModel(640, 480, 300, 300, 320, 240, "equidistant", [0.1, 0, 0, 0])
    assert fisheye.coefficients == [0.1, 0, 0, 0]


def test_bad_camera_models_raise_value_error():
    with pytest.raises(ValueError, match="project: points"):
        camera().project(np.zeros((4, 2)))
    with pytest.raises(ValueError, match="takes 5 coefficients, got 3"):
        lidartag.CameraModel(1280, 720, 900, 900, 640, 360, "plumb_bob", [0.1, 0.0, 0.0])
    with pytest.raises(ValueError, match="distortion must be"):
        lidartag.CameraModel(1280, 720, 900, 900, 640, 360, "rational_polynomial", [0] * 8)
    with pytest.raises(ValueError, match="CameraModel"):
        lidartag.CameraModel(1280, 720, -900, 900, 640, 360)
    with pytest.raises(ValueError, match="CameraModel"):
        lidartag.CameraModel(1280, 720, 900, 900, 2000, 360)
    with pytest.raises(ValueError, match="CameraModel"):
        lidartag.CameraModel(0, 720, 900, 900, 640, 360)


def test_load_intrinsics_reads_ros_camera_info(tmp_path):
    path = tmp_path / "camera.yaml"
    path.write_text(CAMERA_INFO)
    cam = lidartag.load_intrinsics(path)
    assert (cam.width, cam.height) == (1280, 720)
    assert (cam.fx, cam.fy, cam.cx, cam.cy) == (905.5, 903.5, 641.25, 358.75)
    assert cam.distortion == "plumb_bob"
    assert cam.coefficients == [-0.12, 0.05, 0.0008, -0.0006, -0.01]
    points = np.array([[0.4, 0.3, 2.0], [-1.0, 0.2, 4.0]])
    np.testing.assert_array_equal(cam.project(points), camera().project(points))


def test_load_intrinsics_names_the_bad_key(tmp_path):
    path = tmp_path / "broken.yaml"
    path.write_text(CAMERA_INFO.replace("data: [905.5, 0, 641.25, 0, 903.5, 358.75, 0, 0, 1]",
                                        "data: [905.5, 0, 641.25, 0, 903.5, 358.75]"))
    with pytest.raises(lidartag.IntrinsicsError, match="camera_matrix"):
        lidartag.load_intrinsics(path)
    with pytest.raises(lidartag.IntrinsicsError):
        lidartag.load_intrinsics(tmp_path / "missing.yaml")


def test_detect_image_tags_on_the_tag_sheet():
    sheet = SOURCE_DIR / "docs" / "tag-sheet.png"
    if not sheet.exists():
        pytest.skip(f"no {sheet}")
    tags = lidartag.detect_image_tags(sheet, families=["tag16h5"])
    assert [(t["family"], t["id"]) for t in tags] == [("tag16h5", i) for i in range(6)]
    for t in tags:
        c = t["corners"]
        assert c.shape == (4, 2)
        # Upright on the sheet: bottom-left, bottom-right, top-right, top-left (v grows down).
        assert c[0, 0] < c[1, 0] and c[0, 1] > c[3, 1]
        assert c[2, 0] > c[3, 0] and c[2, 1] < c[1, 1]
    pixels = lidartag.read_image(sheet)
    assert pixels.dtype == np.uint8 and pixels.shape == (877, 620)
    from_array = lidartag.detect_image_tags(pixels, families="tag16h5")
    assert len(from_array) == 6
    for a, b in zip(tags, from_array):
        np.testing.assert_allclose(a["corners"], b["corners"], atol=1e-9)
    # Upside down: the same tags, each corner k now the turned image's corner k.
    turned = np.ascontiguousarray(pixels[::-1, ::-1])
    for a, b in zip(tags, lidartag.detect_image_tags(turned, families="tag16h5")):
        np.testing.assert_allclose(b["corners"], [619, 876] - a["corners"], atol=0.05)


def test_detect_image_tags_refuses_what_is_not_a_grey_image():
    with pytest.raises(ValueError, match="uint8"):
        lidartag.detect_image_tags(np.zeros((10, 10), dtype=float))
    with pytest.raises(ValueError, match="uint8"):
        lidartag.detect_image_tags(np.zeros((10, 10, 3), dtype=np.uint8))
    assert lidartag.detect_image_tags(np.full((64, 64), 128, dtype=np.uint8)) == []
    # Images too small for a tag give none (AprilTag 3 itself hangs or crashes on 1 or 2 rows).
    for shape in [(0, 5), (1, 1), (2, 2), (1, 50), (2, 50), (50, 1), (7, 7), (8, 8)]:
        assert lidartag.detect_image_tags(np.zeros(shape, dtype=np.uint8)) == [], shape
    with pytest.raises(lidartag.ImageTagError):
        lidartag.detect_image_tags(np.zeros((8, 8), dtype=np.uint8), families=["tag99h1"])
    with pytest.raises(ValueError, match="decimat"):
        lidartag.detect_image_tags(np.zeros((8, 8), dtype=np.uint8), decimate=0.5)
