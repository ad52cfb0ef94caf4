"""lidartag: Velodyne and Ouster captures into numpy, the LiDARTag detector, the scene simulator
and lidartagd's LCM logs, from Python.

    import lidartag
    for rotation in lidartag.read("pcaps/demo.pcap"):     # lazily, one rotation at a time
        points = rotation.points                           # numpy: x y z range azimuth time ...
    ouster = lidartag.read("os1.pcap", metadata="os1.json")  # or os1.json beside os1.pcap
    detector = lidartag.Detector({"tag_sizes_m": [0.8, 0.6]})
    for rotation, result in lidartag.detect("pcaps/demo.pcap", detector):
        for tag in result:
            print(tag.family, tag.id, tag.position, tag.orientation)

    camera = lidartag.load_intrinsics("camera.yaml")           # ROS camera_info or OpenCV YAML
    result = lidartag.calibrate(camera, image_corners, lidar_corners)   # (P,4,2) px, (P,4,3) m
    print(result.camera_from_lidar, result.sigma, result.warnings)

Every long call (reading, decoding, detecting, simulating, calibrating) runs without the GIL.
"""

import json as _json
import os as _os

from ._lidartag import (  # noqa: F401  (re-exported)
    __version__,
    CalibrationError,
    CameraModel,
    CloudError,
    ConfigError,
    DetectionResult,
    Detection,
    Detector,
    Error,
    ExtrinsicError,
    FamilyError,
    ImageError,
    ImageTagError,
    IntrinsicsError,
    IoError,
    LcmLog,
    LogEvent,
    MetadataError,
    OptionsError,
    OutputError,
    Reader,
    Rotation,
    SceneError,
    lcmtypes,
)
from . import _lidartag

__all__ = [
    "read", "detect", "simulate", "read_lcm_log", "read_pcd", "write_pcd", "Detector",
    "Detection", "DetectionResult", "Rotation", "Reader", "LcmLog", "LogEvent", "lcmtypes",
    "Error", "IoError", "CalibrationError", "ConfigError", "OptionsError", "CloudError",
    "FamilyError", "SceneError", "OutputError", "CameraModel", "load_intrinsics", "calibrate",
    "CalibrationResult", "detect_image_tags", "read_image", "ExtrinsicError", "IntrinsicsError",
    "ImageError", "ImageTagError", "MetadataError", "ring_elevations", "ring_spacing_covariance",
    "detection_covariance",
]


def read(path, model=None, calibration=None, cut_deg=180.0, partial=False, data_port=None,
         position_port=None, sensor=None, rings=0, resolution_deg=0.0, topic=None, start=0.0,
         duration=None, metadata=None, intensity="reflectivity"):
    """The rotations of a capture, read lazily: a pcap/pcapng of Velodyne or Ouster packets, a ROS
    bag or MCAP file, or a PCD file (one rotation).

    Packet captures are opened by content as lidartagd opens them (the driver's source seam):
    - a pcap of Ouster packets with its sensor's metadata JSON: `metadata`, or NAME.json beside
      NAME.pcap (a JSON there that holds no beam intrinsics, such as a simulator's truth file, is
      not taken for metadata); without either, a pcap is read as Velodyne packets;
    - a ROS 1 bag, ROS 2 bag folder or MCAP file (recognised by content) on its LiDAR topic:
      velodyne_msgs/VelodyneScan packets as the pcap of those packets; ouster_ros/PacketMsg
      packets with the metadata from the bag's metadata topic (or `metadata`), IMU packets counted
      apart; sensor_msgs/PointCloud2 clouds each as one Rotation (as Rotation.from_points makes
      it: the cloud's ring field, or rings from `model`'s elevations or `rings` estimated; stamped
      with the cloud's header stamp).
    An Ouster rotation is one frame of the sensor, destaggered (a column's cells point the same
    way), ring 0 the lowest beam; its model is the metadata's ("os0-128"), its return_mode the
    packet profile ("RNG15_RFL8_NIR8").

    topic: the bag's LiDAR topic; None: its one LiDAR topic.
    start, duration: a time window, seconds from a bag's first message or a pcap's first packet
      (None: to the end); what falls outside is counted in counts["outside_window"].
    model: decode as this Velodyne model (vlp16, puck-hires, vlp32c, hdl32e, vls128); None: the
      packets' product byte, checked against their timing (Reader.model_mismatch says when they
      disagree). An Ouster model name (os0-128, os1-64, ...): the metadata must describe it
      (MetadataError otherwise; ValueError for a pcap without metadata). For PCD files and
      PointCloud2 clouds without a ring field, the model's beam elevations place the rings (an
      Ouster model's nominal ones).
    calibration: a Velodyne calibration file (ros-drivers YAML or VeloView XML); None: the
      built-in table.
    metadata: an Ouster sensor's metadata JSON (either layout); the capture is then read as Ouster
      packets. MetadataError for a file that cannot describe a sensor (naming the key), and at the
      end of a capture none of whose packets it describes.
    intensity: Ouster: the points' intensity, "reflectivity" (calibrated reflectivity, 0-255: what
      the detector's thresholds assume; the default) or "signal" (signal photons clamped to 255;
      RNG19 profiles and LEGACY only, ValueError for RNG15).
    cut_deg: azimuth where Velodyne rotations are cut, degrees (Ouster frames end where the frame
      id changes).
    partial: also yield incomplete rotations (the first and last, and those with lost packets).
    data_port, position_port: which UDP ports are the sensor's data and auxiliary packets; None:
      the vendor's (Velodyne 2368 and 8308, Ouster lidar 7502 and IMU 7503).
    sensor: only packets from this IPv4 address (pcaps).
    rings, resolution_deg: PCD files and PointCloud2 clouds without a ring field and no model:
      beams to regress; column width when a cloud's points are binned by azimuth.
    Returns a Reader: iterate it (`for rotation in lidartag.read(path)`), or list() it; its
    vendor, model, sensor_info (Ouster metadata) and counts say what was read.
    """
    options = _lidartag._ReaderOptions()
    options.model = model
    options.calibration = None if calibration is None else _os.fspath(calibration)
    options.sensor = sensor
    options.cut_deg = float(cut_deg)
    options.partial = bool(partial)
    options.data_port = None if data_port is None else int(data_port)
    options.position_port = None if position_port is None else int(position_port)
    options.rings = int(rings)
    options.resolution_deg = float(resolution_deg)
    options.topic = topic
    options.start_s = float(start)
    options.duration_s = float("inf") if duration is None else float(duration)
    options.metadata = None if metadata is None else _os.fspath(metadata)
    options.intensity = str(intensity)
    return Reader(_os.fspath(path), options)


def detect(source, detector=None, **read_options):
    """Yields (rotation, DetectionResult) for every rotation of `source`.

    source: a capture or PCD path (read with `read_options`, see read()), or an iterable of
      Rotation. detector: a Detector, or its config (None, a dict, a YAML path or text).
    """
    if not isinstance(detector, Detector):
        detector = Detector(detector)
    rotations = read(source, **read_options) if isinstance(source, (str, _os.PathLike)) \
        else source
    for rotation in rotations:
        yield rotation, detector.detect(rotation)


def _scene_text(scene):
    """(text, is_path) of a scene: a path, YAML text, or a dict."""
    if isinstance(scene, _os.PathLike):
        return _os.fspath(scene), True
    if isinstance(scene, str):
        return (scene, True) if _os.path.isfile(scene) else (scene, False)
    if isinstance(scene, dict):
        # JSON is YAML: the scene loader reads it as it reads the YAML files.
        return _json.dumps(scene), False
    raise TypeError("scene: a path, a YAML string or a dict")


def simulate(scene, out=None, rotations=None, seed=None, partial=False):
    """Simulates a scene (see docs/simulator.md): a scene file path, YAML text, or a dict.

    With `out` (a .pcap path): writes the capture a real sensor would record and returns the
    ground truth (a dict, as `lidartag sim --truth` writes it); an Ouster sensor's metadata goes
    beside it (NAME.json for NAME.pcap), as `lidartag sim` writes it, so read(out) finds it.
    Without: returns (rotations, truth): the packets decoded in memory into the complete
    rotations (all of them with partial=True; an Ouster sensor's frames as read() gives them),
    each matching truth["rotations"][i].
    rotations, seed: override the scene's.
    """
    text, is_path = _scene_text(scene)
    truth_json, decoded, stats = _lidartag._simulate(
        text, is_path, "" if out is None else _os.fspath(out), rotations, seed, bool(partial))
    truth = _json.loads(truth_json)
    truth["packets"] = stats
    return truth if out is not None else (decoded, truth)


def _status_names():
    """status_t in words: the sender addresses as dotted quads (the LCM field is int32, so
    192.168.1.201 reads -1062731319) and the state, PPS and time source by name (the names
    lidartagd's STATUS= line and logs use)."""
    status_t = lcmtypes.status_t

    def names(prefix):
        return {getattr(status_t, n): n[len(prefix):].lower().replace("_", " ")
                for n in dir(status_t) if n.startswith(prefix)}

    states, pps, sources = names("STATE_"), names("PPS_"), names("TIME_")

    def dotted(value):
        v = value & 0xFFFFFFFF
        return "%d.%d.%d.%d" % (v >> 24, (v >> 16) & 255, (v >> 8) & 255, v & 255)

    status_t.sender_addresses = property(
        lambda m: [dotted(int(a)) for a in m.senders],
        doc="senders as dotted quads ('192.168.1.201')")
    status_t.state_name = property(lambda m: states.get(m.state, "unknown"),
                                   doc="state by name ('healthy', 'not decoding', ...)")
    status_t.pps_name = property(lambda m: pps.get(m.pps, "unknown"),
                                 doc="PPS state by name ('absent', 'locked', ...)")
    status_t.time_source_name = property(lambda m: sources.get(m.time_source, "unknown"),
                                         doc="'host' or 'gps'")


_status_names()


def read_lcm_log(path):
    """Every message of an LCM log of lidartagd, grouped by type.

    Returns a dict: type name ('tag_detections_t', 'status_t', 'raw_packet_t', 'tag_points_t',
    'point_cloud_t') -> list of (channel, utime, message), and 'counts' (events, decoded by type,
    malformed, unknown, truncated). Malformed events are counted, not fatal. For a lazy read,
    iterate lidartag.LcmLog(path).
    """
    log = LcmLog(_os.fspath(path))
    out = {}
    for event in log:
        if event.message is not None:
            out.setdefault(event.type, []).append((event.channel, event.utime, event.message))
    out["counts"] = log.counts
    return out


def read_pcd(path):
    """A PCD file (ascii, binary or binary_compressed) as a dict: 'fields' (name -> numpy float64
    array; shaped (height, width) for organised clouds), 'width', 'height', 'format',
    'skipped_fields', and from `lidartag dump`'s header comments 'stamp_ns', 'sequence', 'model'
    (None when absent). For the rotation of a PCD, use read(path)."""
    return _lidartag._read_pcd(_os.fspath(path))


def write_pcd(rotation, path, format="binary", organized=False):
    """Writes a Rotation as `lidartag dump` does (format: ascii, binary, binary_compressed;
    organized: rings x columns with NaN where there is no return). Returns the points written."""
    return _lidartag._write_pcd(rotation, _os.fspath(path), format, bool(organized))


def message_dict(message):
    """A lidartag.lcmtypes message as a dict of its fields (nested messages as dicts)."""
    def value(v):
        if hasattr(type(v), "fields") and hasattr(type(v), "fingerprint"):
            return message_dict(v)
        if isinstance(v, list):
            return [value(x) for x in v]
        return v
    return {name: value(getattr(message, name)) for name in type(message).fields}


def load_intrinsics(path):
    """A CameraModel from a ROS camera_info YAML or an OpenCV FileStorage YAML (docs/camera.md).
    Raises IntrinsicsError naming the file and the key when it cannot be used."""
    return _lidartag._load_intrinsics(_os.fspath(path))


class CalibrationResult:
    """The camera-from-LiDAR extrinsic solved by calibrate().

    camera_from_lidar: 4x4 numpy, maps LiDAR points (m) into the camera's optical frame (x right,
      y down, z forward); lidar_from_camera its inverse; rotation_wxyz, translation_m (numpy).
    sigma: 1-sigma dict (rotation_deg [x y z], rotation_total_deg, translation_mm [x y z],
      covariance 6x6: rotation vector rad on the camera side, translation m).
    rms_px, held_out_median_px, held_out_max_px (-1 with fewer than 2 poses); poses (one dict per
      input pose: label, used, reason, corner_px, rms_px, held_out_px, range_m, chi2);
      rejected [{label, reason}]; warnings; weak (weak directions: name, sigma_deg, direction);
      suggestion (the pose to add next, '' when nothing is weak); forms (urdf, ros1, ros2,
      opencv_yaml text).
    json: the dict of `lidartag calibrate --json` (calibration_json); to_json() its text.
    """

    def __init__(self, json_dict):
        import numpy as np
        self.json = json_dict
        l2c = json_dict["lidar_to_camera"]
        self.camera_from_lidar = np.array(l2c["matrix"], dtype=float)
        self.lidar_from_camera = np.array(l2c["inverse"], dtype=float)
        self.rotation_wxyz = np.array(l2c["rotation_wxyz"], dtype=float)
        self.translation_m = np.array(l2c["translation_m"], dtype=float)
        self.sigma = dict(l2c["sigma"])
        self.sigma["covariance"] = np.array(self.sigma["covariance"], dtype=float)
        errors = json_dict["errors"]
        self.rms_px = errors["rms_px"]
        self.held_out_median_px = errors["held_out_median_px"]
        self.held_out_max_px = errors["held_out_max_px"]
        self.poses = json_dict["poses"]
        self.poses_used = json_dict["poses_used"]
        self.rejected = json_dict["poses_rejected"]
        self.warnings = json_dict["warnings"]
        self.weak = json_dict["degeneracy"]["weak"]
        self.suggestion = json_dict["degeneracy"]["suggestion"]
        self.forms = json_dict["forms"]

    def to_json(self, indent=2):
        """The result as `lidartag calibrate --json` writes it (text)."""
        return _json.dumps(self.json, indent=indent)

    def __repr__(self):
        return "<lidartag.CalibrationResult %d/%d poses, rms %.3f px, sigma %.3f deg %s mm>" % (
            self.poses_used, len(self.poses), self.rms_px, self.sigma["rotation_total_deg"],
            self.sigma["translation_mm"])


def _per_pose(value, count, name):
    """A scalar or one value per pose, as a float64 array of `count` finite positive values."""
    import numpy as np
    a = np.asarray(value, dtype=float)
    if a.ndim == 0:
        a = np.full(count, float(a))
    if a.shape != (count,):
        raise ValueError("calibrate: %s: a number or one per pose (%d), got shape %s"
                         % (name, count, a.shape))
    if not np.all(np.isfinite(a)) or np.any(a <= 0):
        raise ValueError("calibrate: %s must be finite and positive" % name)
    return a


def ring_elevations(rotation):
    """The elevation of each ring of `rotation` that has returns, radians (numpy, lowest first):
    the mean atan2(z, hypot(x, y)) of its first returns, as `lidartag calibrate` measures the
    rings a capture's tags were cut by (see ring_spacing_covariance)."""
    return _lidartag._ring_elevations(rotation)


def _corner_array(lidar_corners, what):
    """(P, 4, 3) float64 corners and whether one pose (4, 3) was given."""
    import numpy as np
    corners = np.asarray(lidar_corners, dtype=float)
    single = corners.shape == (4, 3)
    if single:
        corners = corners[None]
    if corners.ndim != 3 or corners.shape[1:] != (4, 3) or corners.shape[0] < 1:
        raise ValueError("%s: lidar_corners must be shaped (P, 4, 3) or (4, 3), got %s"
                         % (what, corners.shape))
    return np.ascontiguousarray(corners), single


def _elevation_lists(value, count, what):
    """One list of ring elevations (radians) per pose from a Rotation, an array of radians (the
    same rings for every pose), or a sequence of `count` of those."""
    import numpy as np
    if isinstance(value, Rotation):
        return [list(ring_elevations(value))] * count
    if isinstance(value, (list, tuple)) and len(value) == count and count > 0 and all(
            isinstance(v, Rotation) or np.ndim(v) == 1 for v in value):
        return [list(ring_elevations(v)) if isinstance(v, Rotation)
                else [float(x) for x in np.asarray(v, dtype=float)] for v in value]
    a = np.asarray(value, dtype=float)
    if a.ndim != 1:
        raise ValueError("%s: ring_elevations: a Rotation, a 1-D array of radians, or one of "
                         "those per pose (%d)" % (what, count))
    return [[float(x) for x in a]] * count


def ring_spacing_covariance(lidar_corners, ring_elevations):
    """What the LiDAR's ring spacing leaves unknown in each tag's corners (m^2), the term
    `lidartag calibrate` adds to every LiDAR tag (calib::add_ring_spacing_uncertainty): a tag whose
    edges run along the rings (a square mount) is cut by the same rings every rotation, so its
    position across the rings is known only to gap / sqrt(12), which no averaging shows; zero for
    a tag turned away from the rings (a diamond).

    lidar_corners: (P, 4, 3) or (4, 3) metres, LiDAR frame, calibrate()'s corner order
      (Detection.corners); the tag's pose and size are taken from them.
    ring_elevations: the sensor's rings, radians: a Rotation (its rings with returns, see
      ring_elevations()), a 1-D array, or one of those per pose.
    Returns (P, 12, 12) (or (12, 12) for one pose), corner-major as calibrate's lidar_covariance.
    """
    corners, single = _corner_array(lidar_corners, "ring_spacing_covariance")
    lists = _elevation_lists(ring_elevations, corners.shape[0], "ring_spacing_covariance")
    out = _lidartag._ring_spacing_covariance(corners, lists)
    return out[0] if single else out


def detection_covariance(lidar_corners, position_sigma_m=0.003, angle_sigma_deg=0.2,
                         floor_m=0.002):
    """The corners' covariance (m^2) `lidartag calibrate` gives a tag seen in one rotation
    (calib::lidar_tag_from_detection): the tag's pose known to position_sigma_m per axis and
    angle_sigma_deg per axis, plus floor_m on every coordinate. (For captures of several rotations
    the CLI takes the tracker's window over them instead.)

    lidar_corners: (P, 4, 3) or (4, 3) metres (Detection.corners).
    Returns (P, 12, 12) (or (12, 12)), corner-major as calibrate's lidar_covariance.
    """
    corners, single = _corner_array(lidar_corners, "detection_covariance")
    out = _lidartag._detection_covariance(corners, float(position_sigma_m),
                                          float(angle_sigma_deg), float(floor_m))
    return out[0] if single else out


def calibrate(camera, image_corners, lidar_corners, sigma_px=0.3, lidar_sigma_m=0.004,
              labels=None, lidar_covariance=None, held_out=True, lidar_frame="lidar",
              camera_frame="camera_optical_frame", ring_elevations=None):
    """The camera-from-LiDAR extrinsic from tag poses seen by both sensors (docs/calibration.md).

    camera: a CameraModel (load_intrinsics, or built from numbers).
    image_corners: (P, 4, 2) pixels, corner k of pose p in lidartag's convention ((0, 0) the centre
      of the top-left pixel; corner k as docs/calibration.md "The corner order" says: AprilTag 3's
      p[k], as detect_image_tags gives them).
    lidar_corners: (P, 4, 3) metres in the LiDAR frame, the same corners (Detection.corners).
    sigma_px: the image corners' 1-sigma, pixels: a number or one per pose.
    lidar_sigma_m: each LiDAR corner coordinate's 1-sigma, metres (independent, isotropic): a number
      or one per pose. Default 4 mm: one rotation's detection at 5 m (docs/calibration.md).
    lidar_covariance: instead, each pose's joint corner covariance (P, 12, 12), m^2, corner-major.
    ring_elevations: the LiDAR's rings (a Rotation of the capture, a 1-D array of radians, or
      one of those per pose): adds ring_spacing_covariance() to each pose's covariance, as
      `lidartag calibrate` always does (it knows its captures' rings). None (default): the
      covariance given (lidar_sigma_m or lidar_covariance) is used as it is. With
      lidar_covariance=detection_covariance(corners) and the rotation's ring_elevations, one
      rotation's detections give what `lidartag calibrate` gives on a one-rotation capture.
    labels: names of the poses in the result (default "pose 0", "pose 1", ...).
    held_out: compute each pose's leave-one-out error (one more solve per pose).
    Returns a CalibrationResult. Raises ValueError for arrays of the wrong shape, non-finite values
    or no pose; ExtrinsicError when no pose gives a solution.
    """
    import numpy as np
    if not isinstance(camera, CameraModel):
        raise TypeError("calibrate: camera must be a lidartag.CameraModel (load_intrinsics)")
    image = np.asarray(image_corners, dtype=float)
    lidar = np.asarray(lidar_corners, dtype=float)
    if image.ndim != 3 or image.shape[1:] != (4, 2):
        raise ValueError("calibrate: image_corners must be shaped (P, 4, 2), got %s"
                         % (image.shape,))
    if lidar.ndim != 3 or lidar.shape[1:] != (4, 3):
        raise ValueError("calibrate: lidar_corners must be shaped (P, 4, 3), got %s"
                         % (lidar.shape,))
    count = image.shape[0]
    if count < 1:
        raise ValueError("calibrate: no pose (image_corners has 0)")
    if lidar.shape[0] != count:
        raise ValueError("calibrate: %d poses of image corners but %d of LiDAR corners"
                         % (count, lidar.shape[0]))
    for name, a in (("image_corners", image), ("lidar_corners", lidar)):
        bad = np.flatnonzero(~np.all(np.isfinite(a.reshape(count, -1)), axis=1))
        if bad.size:
            raise ValueError("calibrate: %s of pose %d is not finite" % (name, bad[0]))
    sigma = _per_pose(sigma_px, count, "sigma_px")
    if lidar_covariance is None:
        lidar_sigma = _per_pose(lidar_sigma_m, count, "lidar_sigma_m")
        cov = (lidar_sigma ** 2)[:, None, None] * np.eye(12)[None, :, :]
    else:
        cov = np.asarray(lidar_covariance, dtype=float)
        if cov.shape != (count, 12, 12):
            raise ValueError("calibrate: lidar_covariance must be shaped (%d, 12, 12), got %s"
                             % (count, cov.shape))
        if not np.all(np.isfinite(cov)):
            raise ValueError("calibrate: lidar_covariance is not finite")
    if ring_elevations is not None:
        cov = cov + ring_spacing_covariance(lidar, _elevation_lists(ring_elevations, count,
                                                                    "calibrate"))
    if labels is None:
        labels = ["pose %d" % i for i in range(count)]
    labels = [str(label) for label in labels]
    if len(labels) != count:
        raise ValueError("calibrate: %d labels for %d poses" % (len(labels), count))
    text = _lidartag._calibrate(camera, image, lidar, sigma, cov, labels, bool(held_out),
                                str(lidar_frame), str(camera_frame))
    return CalibrationResult(_json.loads(text))


def read_image(path):
    """A PNG or JPEG file as a (H, W) uint8 grey array, row 0 the top (colour converted by libpng /
    libjpeg). Raises ImageError for an unreadable, unknown or corrupt file."""
    return _lidartag._read_image(_os.fspath(path))


def detect_image_tags(image, families=("tag36h11",), camera=None, decimate=1.0,
                      min_decision_margin=0.0):
    """AprilTag 3 tags (with lidartag's corner refinement) in a grey image: a PNG/JPEG path or a
    (H, W) uint8 array. camera: a CameraModel whose lens the corner refinement undoes (its size
    must be the image's). Returns a list of dicts sorted by family and id: family, id, hamming,
    decision_margin, corners ((4, 2) pixels, lidartag's convention, corner k as calibrate wants
    it), center."""
    import numpy as np
    families = [families] if isinstance(families, str) else [str(f) for f in families]
    if isinstance(image, (str, _os.PathLike)):
        return _lidartag._detect_image_tags(_os.fspath(image), None, families, camera,
                                            float(decimate), float(min_decision_margin))
    pixels = np.asarray(image)
    if pixels.dtype != np.uint8 or pixels.ndim != 2:
        raise ValueError("detect_image_tags: image must be a path or a (H, W) uint8 array, got "
                         "%s %s" % (pixels.dtype, pixels.shape))
    return _lidartag._detect_image_tags("", np.ascontiguousarray(pixels), families, camera,
                                        float(decimate), float(min_decision_margin))
