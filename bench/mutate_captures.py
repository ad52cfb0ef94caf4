#!/usr/bin/python3
"""Deterministic mutations of pcap captures, for comparing two builds' scan assembly.

    bench/mutate_captures.py OUT_DIR CAPTURE.pcap ...

Per capture: loss (every 7th data packet and a run of 30), reordered payloads (swapped with the
next, the one after, 3 and 10 later), duplicates (at once and 3 later), garbage and stray packets
(random payloads, packets from elsewhere, runs of 3), the capture twice (a replay's loop), a
fifth cut out of the middle (a time jump); and the first capture followed by the second and the
third (model and return-mode changes). Seeded by the capture's name: the same files every run.
"""
import random, struct, sys, pathlib
def read(path):
    b = pathlib.Path(path).read_bytes()
    gh, off, recs = b[:24], 24, []
    while off + 16 <= len(b):
        ts, tu, incl, orig = struct.unpack_from("<IIII", b, off)
        recs.append([ts, tu, bytearray(b[off + 16: off + 16 + incl])])
        off += 16 + incl
    return gh, recs
def write(path, gh, recs):
    out = bytearray(gh)
    for ts, tu, data in recs:
        out += struct.pack("<IIII", ts, tu, len(data), len(data)) + data
    pathlib.Path(path).write_bytes(out)
def data(r): return len(r[2]) == 42 + 1206
out = pathlib.Path(sys.argv[1]); out.mkdir(exist_ok=True)
caps = sys.argv[2:]
for cap in caps:
    name = pathlib.Path(cap).stem
    gh, recs = read(cap)
    rng = random.Random(name)
    def save(tag, rs): write(out / f"{name}.{tag}.pcap", gh, rs)
    # loss: every 7th data packet and a run of 30
    rs = [r for i, r in enumerate(recs) if not (data(r) and (i % 7 == 3 or 200 <= i < 230))]
    save("loss", rs)
    # reorder payloads: adjacent swaps, some moved 3 and 10 later
    rs = [[a, b, bytearray(c)] for a, b, c in recs]
    idx = [i for i, r in enumerate(rs) if data(r)]
    for k in range(0, len(idx) - 12, 9):
        i, j = idx[k], idx[k + rng.choice([1, 1, 2, 3, 10])]
        rs[i][2][42:], rs[j][2][42:] = rs[j][2][42:], rs[i][2][42:]
    save("reorder", rs)
    # duplicates: immediately and 3 later
    rs = []
    for i, r in enumerate(recs):
        rs.append(r)
        if data(r) and i % 11 == 5: rs.append(r)
        if data(r) and i % 13 == 7 and i >= 3: rs.append(recs[i - 3])
    save("dup", rs)
    # garbage and strays: random payloads, packets from elsewhere in the capture
    rs = []
    for i, r in enumerate(recs):
        rs.append(r)
        if data(r) and i % 17 == 9:
            g = bytearray(r[2]); g[42:] = bytes(rng.getrandbits(8) for _ in range(1206)); rs.append([r[0], r[1], g])
        if data(r) and i % 29 == 11:
            rs.append([r[0], r[1], recs[rng.randrange(len(recs))][2]])
        if data(r) and i % 31 == 13:  # a stray run of 3 consecutive far packets
            j = rng.randrange(len(recs) - 3); rs.extend([[r[0], r[1], recs[j + m][2]] for m in range(3)])
    save("garbage", rs)
    # loop: the capture twice (time jumps back)
    save("loop", recs + recs)
    # jump: a fifth of the capture cut out of its middle
    half = len(recs) // 2
    save("jump", recs[:half] + recs[half + len(recs)//5:])
# model and mode changes: captures concatenated
gh, a = read(caps[0])
for other in caps[1:3]:
    _, b = read(other)
    write(out / f"concat.{pathlib.Path(caps[0]).stem}.{pathlib.Path(other).stem}.pcap", gh, a + b)
