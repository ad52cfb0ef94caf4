"""lidartag: Velodyne captures into numpy, the LiDARTag detector, the scene simulator and
lidartagd's LCM logs, from Python.

    import lidartag
    for rotation in lidartag.read("pcaps/demo.pcap"):     # lazily, one rotation at a time
        points = rotation.points                           # numpy: x y z range azimuth time ...
    detector = lidartag.Detector({"tag_sizes_m": [0.8, 0.6]})
    for rotation, result in lidartag.detect("pcaps/demo.pcap", detector):
        for tag in result:
            print(tag.family, tag.id, tag.position, tag.orientation)

Every long call (reading, decoding, detecting, simulating) runs without the GIL.
"""

import json as _json
import os as _os

from ._lidartag import (  # noqa: F401  (re-exported)
    __version__,
    CalibrationError,
    CloudError,
    ConfigError,
    DetectionResult,
    Detection,
    Detector,
    Error,
    FamilyError,
    IoError,
    LcmLog,
    LogEvent,
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
    "FamilyError", "SceneError", "OutputError",
]


def read(path, model=None, calibration=None, cut_deg=180.0, partial=False, data_port=2368,
         position_port=8308, sensor=None, rings=0, resolution_deg=0.2):
    """The rotations of a pcap/pcapng capture (or of a PCD file: one rotation), read lazily.

    A ROS 1 bag, ROS 2 bag folder or MCAP file of velodyne_msgs/VelodyneScan packets is read as
    the pcap of those packets (recognised by content; its one LiDAR topic).

    model: decode as this model (vlp16, puck-hires, vlp32c, hdl32e, vls128); None: the packets'
      product byte, checked against their timing (Reader.model_mismatch says when they disagree).
    calibration: a calibration file (ros-drivers YAML or VeloView XML); None: the built-in table.
    cut_deg: azimuth where rotations are cut, degrees.
    partial: also yield incomplete rotations (the first and last, and those with lost packets).
    data_port, position_port, sensor: which packets are the sensor's (sensor: an IPv4 address).
    rings, resolution_deg: PCD files without a ring field and no model: beams to regress; column
      width when a PCD's points are binned by azimuth.
    Returns a Reader: iterate it (`for rotation in lidartag.read(path)`), or list() it.
    """
    options = _lidartag._ReaderOptions()
    options.model = model
    options.calibration = None if calibration is None else _os.fspath(calibration)
    options.sensor = sensor
    options.cut_deg = float(cut_deg)
    options.partial = bool(partial)
    options.data_port = int(data_port)
    options.position_port = int(position_port)
    options.rings = int(rings)
    options.resolution_deg = float(resolution_deg)
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
    ground truth (a dict, as `lidartag sim --truth` writes it).
    Without: returns (rotations, truth): the packets decoded in memory into the complete
    rotations (all of them with partial=True), each matching truth["rotations"][i].
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
