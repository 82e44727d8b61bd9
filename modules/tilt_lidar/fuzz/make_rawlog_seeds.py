#!/usr/bin/env python3
"""Writes the hand-made seeds of the rawlog fuzz corpus (corpus/rawlog/): small valid
rawlogs in MRPT 2.x's serialisation and the hostile cases the bounded reader must refuse.
Run from this folder: python3 make_rawlog_seeds.py"""
import gzip
import os
import random
import struct

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "corpus", "rawlog")
END = b"\x88"


def header(name, version):
    n = name.encode()
    return bytes([0x80 | len(n)]) + n + bytes([version])


def string(s, claimed=None):
    b = s.encode()
    return struct.pack("<I", len(b) if claimed is None else claimed) + b


def vec(fmt, values, claimed=None):
    return struct.pack("<I", len(values) if claimed is None else claimed) + b"".join(
        struct.pack("<" + fmt, v) for v in values)


def pose3d_v3():
    return header("mrpt::poses::CPose3D", 3) + struct.pack("<12d", 0, 0, 0.1, 1, 0, 0, 0, 1, 0, 0, 0, 1) + END


def pose3d_v1(rows=4, cols=4):
    m = struct.pack("<II", rows, cols) + struct.pack("<16d", *[1.0 if i % 5 == 0 else 0.0 for i in range(16)])
    return header("CPose3D", 1) + header("CMatrixD", 0) + m + END + END


def scan(t, ranges, label="HOKUYO", version=7, count=None, label_len=None, pose=None):
    n = len(ranges)
    body = struct.pack("<f?f", 4.712389, True, 30.0) + (pose or pose3d_v3())
    body += struct.pack("<I", n if count is None else count)
    body += struct.pack("<%df" % n, *ranges) + bytes([1] * n)
    body += struct.pack("<f", 0.01) + struct.pack("<q", t) + struct.pack("<f", 0.0)
    body += string(label, label_len) + struct.pack("<d", 0.0)
    if version >= 7:
        body += b"\x01" + struct.pack("<%di" % n, *range(n))
    return header("mrpt::obs::CObservation2DRangeScan", version) + body + END


def daq(t, count, angle, label="TILT_ENCODER", ain8_claimed=None):
    body = string(label) + struct.pack("<q", t) + struct.pack("<d", 0.0)
    body += vec("B", [], ain8_claimed) + vec("H", []) + vec("I", []) + vec("f", []) + vec("d", [angle])
    body += struct.pack("<H?", 0, True)
    body += vec("B", []) + vec("H", []) + vec("f", []) + vec("d", []) + vec("B", []) + vec("B", [])
    body += vec("I", []) + vec("d", [count])
    return header("mrpt::obs::CObservationRawDAQ", 0) + body + END


def frame(observations, claimed=None):
    return (header("CSensoryFrame", 2) + struct.pack("<I", len(observations) if claimed is None else claimed)
            + b"".join(observations) + END)


T0 = 638000000000000000  # mrpt::Clock ticks (100 ns since 1601)
TICK = 10000000  # 1 s
RANGES = [1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5]


def write(name, data):
    with open(os.path.join(OUT, name), "wb") as f:
        f.write(data)


os.makedirs(OUT, exist_ok=True)
valid = (daq(T0, 100.0, 0.01) + scan(T0 + TICK // 40, RANGES) + daq(T0 + TICK // 200, 200.0, 0.02)
         + scan(T0 + 2 * TICK // 40, RANGES))
write("valid_scans_encoder", valid)
write("valid_scans_encoder_gz", gzip.compress(valid, mtime=0))
write("valid_sensory_frame", frame([scan(T0, RANGES, label="", version=6, pose=pose3d_v1())]) * 2)
write("forged_beam_count", scan(T0, RANGES, count=0xFFFFFFF0) + b"\0" * 64)
write("forged_beam_count_gz", gzip.compress(scan(T0, RANGES, count=0xFFFFFFF0) + b"\0" * 64, mtime=0))
write("count_beyond_file", scan(T0, RANGES, count=19999))
rng = random.Random(7)
write("gzip_garbage", gzip.compress(bytes(rng.randrange(256) for _ in range(512)), mtime=0))
write("empty", b"")
write("frame_huge_count", frame([scan(T0, RANGES)], claimed=0xFFFFFFFF))
write("daq_huge_vector", daq(T0, 1.0, 0.0, ain8_claimed=0x7FFFFFFF))
write("pose_huge_matrix", scan(T0, RANGES, version=6, pose=pose3d_v1(0xFFFF, 0xFFFF)))
write("label_huge", scan(T0, RANGES, label_len=0xFFFFFFFF))
write("nan_ranges", daq(T0, 1.0, 0.0) + scan(T0 + 1, [float("nan"), -1.0, float("inf")] + RANGES[3:]))
write("top_level_map", header("mrpt::maps::CSimplePointsMap", 0) + struct.pack("<I", 0xFFFFFFF0) + b"\0" * 32)
write("scan_bool_16", scan(T0, RANGES).replace(struct.pack("<f?f", 4.712389, True, 30.0), struct.pack("<fBf", 4.712389, 16, 30.0)))
write("old_format_header", struct.pack("<I", 7) + b"CPose3D" + struct.pack("<i", 3) + b"\0" * 96)
