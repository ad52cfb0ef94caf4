"""lidartagd's LCM logs read into Python objects with the project's generated C++ types."""
import re
import struct
import subprocess

import numpy as np
import pytest

import lidartag
from conftest import DEMO_CONFIG, SOURCE_DIR, expect_matches_truth

SYNC = 0xEDA1DA01


@pytest.fixture(scope="module")
def demo_log(lidartagd, demo, tmp_path_factory):
    """The demo replayed by lidartagd with every optional channel, into an LCM log file."""
    path = tmp_path_factory.mktemp("lcm") / "demo.lcmlog"
    subprocess.run([lidartagd, "--config", str(DEMO_CONFIG), "--max-speed", "--log-level", "warn",
                    "--replay", str(demo), "--lcm-url", f"file://{path}?mode=w",
                    "--set", "lcm.publish_raw=true", "--set", "lcm.publish_tag_points=true",
                    "--set", "lcm.cloud_decimation=10"], check=True, timeout=300)
    return path


def events_of(path):
    """(eventnum, utime, channel, data) of every event: LCM's log format, read here by hand."""
    data = path.read_bytes()
    out, pos = [], 0
    while pos + 28 <= len(data):
        sync, num, utime, clen, dlen = struct.unpack_from(">IqqII", data, pos)
        assert sync == SYNC
        pos += 28
        channel = data[pos:pos + clen].decode()
        pos += clen
        out.append((num, utime, channel, data[pos:pos + dlen]))
        pos += dlen
    return out


def write_events(path, events):
    with open(path, "wb") as f:
        for num, utime, channel, data in events:
            c = channel.encode()
            f.write(struct.pack(">IqqII", SYNC, num, utime, len(c), len(data)) + c + data)


def test_the_demo_log_reads_into_messages(demo_log, truth):
    log = lidartag.read_lcm_log(demo_log)
    counts = log["counts"]
    assert counts["malformed"] == counts["unknown"] == 0 and not counts["truncated"]
    assert counts["events"] == counts["decoded"] == len(events_of(demo_log))
    by_type = counts["by_type"]
    assert by_type["tag_detections_t"] == 12  # every rotation, the two partial ones included
    assert by_type["point_cloud_t"] == 12
    assert by_type["status_t"] >= 1
    assert by_type["raw_packet_t"] > 1500
    complete = [m for _, _, m in log["tag_detections_t"] if m.complete]
    assert len(complete) == 10
    for message, expected in zip(complete, truth["rotations"]):
        # utime: microseconds; the truth's stamp is a double (256 ns steps at this magnitude).
        assert abs(message.utime * 1000 - expected["stamp_ns"]) <= 2000
        assert message.ndetections == len(message.detections) == 2
        expect_matches_truth(message.detections, expected)
        d = message.detections[0]
        assert d.position.dtype == np.float64 and d.corners.shape == (4, 3)
    channels = {channel for channel, _, _ in log["tag_detections_t"]}
    assert channels == {"LIDARTAG_DETECTIONS"}
    status = log["status_t"][-1][2]
    # The last status of a replay: the source ended, nothing else wrong (one reason only).
    assert status.state == status.STATE_ENDED and status.reason == "the source ended"
    assert status.healthy is False and status.model == "vlp32c"
    assert status.nstages == len(status.stage_names) == len(status.p50_ms)
    assert status.TIME_HOST == 0 and status.PPS_LOCKED == 2
    # In words (issue 36): state, PPS and time source by name, senders as dotted quads.
    assert status.state_name == "ended" and status.time_source_name in ("host", "gps")
    assert status.pps_name in ("absent", "synchronizing", "locked", "error")
    assert len(status.sender_addresses) == len(status.senders)
    for text, value in zip(status.sender_addresses, status.senders):
        parts = [int(p) for p in text.split(".")]
        assert len(parts) == 4 and all(0 <= p <= 255 for p in parts)
        packed = parts[0] << 24 | parts[1] << 16 | parts[2] << 8 | parts[3]
        assert packed == int(value) & 0xFFFFFFFF
    healthy = [m for _, _, m in log["status_t"] if m.state == m.STATE_HEALTHY]
    assert all(m.state_name == "healthy" for m in healthy)
    raw = log["raw_packet_t"][0][2]
    assert raw.nbytes == len(raw.data) == 1206 and raw.port == 2368
    assert raw.data.dtype == np.uint8 and bytes(raw.data[:2]) == b"\xff\xee"
    points = log["tag_points_t"][0][2]
    assert points.ntags == 2 and points.npoints == len(points.x) == int(points.tag_npoints.sum())
    cloud = log["point_cloud_t"][1][2]
    assert cloud.decimation == 10 and len(cloud.x) == cloud.npoints > 0


def lcm_fields():
    """type name -> field names, from lcmtypes/*.lcm."""
    out = {}
    for path in (SOURCE_DIR / "lcmtypes").glob("*.lcm"):
        text = re.sub(r"//[^\n]*", "", path.read_text())
        for name, body in re.findall(r"struct\s+(\w+)\s*\{(.*?)\}", text, re.S):
            out[name] = [m.group(1) for m in re.finditer(
                r"^\s*(?!const)[\w.]+\s+(\w+)\s*(?:\[[^\]]*\])*\s*;", body, re.M)]
    return out


def test_every_field_of_every_type_is_an_attribute(demo_log):
    fields = lcm_fields()
    assert set(fields) <= {name for name in dir(lidartag.lcmtypes) if not name.startswith("_")}
    seen = set()
    for event in lidartag.LcmLog(demo_log):
        if event.type in seen:
            continue
        seen.add(event.type)
        cls = getattr(lidartag.lcmtypes, event.type)
        assert list(cls.fields) == fields[event.type]
        for name in fields[event.type]:
            getattr(event.message, name)
        as_dict = lidartag.message_dict(event.message)
        assert list(as_dict) == fields[event.type]
    assert seen == {"tag_detections_t", "status_t", "raw_packet_t", "tag_points_t",
                    "point_cloud_t"}


def test_bad_events_are_counted_never_fatal(demo_log, tmp_path):
    events = events_of(demo_log)
    raw = next(e for e in events if e[2] == "LIDARTAG_RAW")
    detections = [e for e in events if e[2] == "LIDARTAG_DETECTIONS"][1]  # rotation #1, 2 tags
    data = bytearray(raw[3])
    # raw_packet_t: hash 8, utime 8, receive_time_ns 8, sensor (4 + n), ipv4 4, port 4, nbytes 4.
    sensor_len = struct.unpack_from(">i", data, 24)[0]
    nbytes_at = 28 + sensor_len + 8
    huge = bytearray(data)
    struct.pack_into(">i", huge, nbytes_at, 0x7FFFFFFF)  # would make decode() allocate 2 GB
    negative = bytearray(data)
    struct.pack_into(">i", negative, nbytes_at, -5)
    crafted = [
        (1, raw[1], "LIDARTAG_RAW", bytes(huge)),
        (2, raw[1], "LIDARTAG_RAW", bytes(negative)),
        (3, raw[1], "LIDARTAG_RAW", bytes(data[:-10])),  # cut short
        (4, raw[1], "LIDARTAG_RAW", bytes(data) + b"\0"),  # a byte too many
        (5, raw[1], "OTHER", b"\x01\x02\x03\x04\x05\x06\x07\x08payload"),  # another type
        (6, raw[1], "SHORT", b"\x01\x02"),
        (7, detections[1], "LIDARTAG_DETECTIONS", detections[3][:40]),
        (8, detections[1], "LIDARTAG_DETECTIONS", detections[3]),  # a good one among them
    ]
    path = tmp_path / "bad.lcmlog"
    write_events(path, crafted)
    seen = list(lidartag.LcmLog(path))
    assert [e.malformed for e in seen] == [True, True, True, True, False, False, True, False]
    assert [e.type for e in seen][4:6] == ["", ""]
    assert seen[7].message.ndetections == 2
    log = lidartag.LcmLog(path)
    list(log)
    counts = log.counts
    assert (counts["events"], counts["decoded"], counts["malformed"], counts["unknown"]) == \
        (8, 1, 5, 2)

    # Seeded byte mutations of real events: every event is accounted for, none raises.
    rng = np.random.default_rng(5)
    mutated = []
    for num, utime, channel, payload in events[:400]:
        b = bytearray(payload)
        for _ in range(int(rng.integers(0, 4))):
            b[int(rng.integers(0, len(b)))] = int(rng.integers(0, 256))
        mutated.append((num, utime, channel, bytes(b)))
    write_events(path, mutated)
    log = lidartag.LcmLog(path)
    n = sum(1 for _ in log)
    c = log.counts
    assert n == c["events"] == 400 == c["decoded"] + c["malformed"] + c["unknown"]
    assert c["malformed"] > 0 and c["decoded"] > 0


def test_a_cut_log_is_truncated(demo_log, tmp_path):
    data = demo_log.read_bytes()
    path = tmp_path / "cut.lcmlog"
    path.write_bytes(data[:len(data) // 2])
    log = lidartag.LcmLog(path)
    n = sum(1 for _ in log)
    assert 0 < n < len(events_of(demo_log))
    assert log.counts["truncated"] is True
    with pytest.raises(lidartag.IoError):
        lidartag.LcmLog(tmp_path / "missing.lcmlog")
