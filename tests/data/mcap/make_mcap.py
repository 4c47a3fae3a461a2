#!/usr/bin/env python3
"""Writes the MCAP test files of vgps from a small simulated drive, with the official
MCAP writers (PyPI `mcap` + `mcap-ros2-support`), so that CI needs neither ROS nor Python.

    vgps simulate --preset short --length-m 5 --images --seed 3 \
        --calibration tests/data/mcap/small_rig.json --out tests/data/mcap/source
    pip install mcap mcap-ros2-support
    python3 tests/data/mcap/make_mcap.py tests/data/mcap/source tests/data/mcap [--complete]
        [--all-compressed]

`--complete` keeps every image; `--all-compressed` writes camera 5 as a CompressedImage too
(six compressed streams, as a Ladybug recording; the raw mono8 of camera 5 is decoded here in
pure Python, far too slow for a long drive).

run.mcap (zstd chunks, as rosbag2 records):
  /ladybug/cam<k>/image/compressed  sensor_msgs/msg/CompressedImage, the drive's PNGs (or
                                    JPEGs, `simulate --jpeg-quality`) as they are, k = 0..4;
                                    stamps = frame time + k ms
  /ladybug/cam5/image_raw           sensor_msgs/msg/Image mono8 (the PNG's pixels)
  frame 2 has no image of camera 4 (a dropped message)
  /gps/fix                          sensor_msgs/msg/NavSatFix from gnss.nmea (status -1
                                    where GGA quality is 0), covariance diag(4, 4, 9) type 2
  /imu/data                         sensor_msgs/msg/Imu, orientation = truth quaternion
  /ladybug/cam0/camera_info         sensor_msgs/msg/CameraInfo (to be ignored)
bad.mcap (uncompressed chunks): an image topic without a camera number, a NavSatFix channel
  in `json` encoding, a NavSatFix with status -1, a truncated CompressedImage, three Imu
  (good, a NaN orientation, a zero quaternion).
"""
import csv
import struct
import sys
import zlib
from decimal import Decimal
from pathlib import Path

from mcap.writer import CompressionType
from mcap.writer import Writer as RawWriter
from mcap_ros2.writer import Writer

HEADER = "builtin_interfaces/Time stamp\nstring frame_id\n"
TIME = "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
SEP = "=" * 80 + "\n"
STD_HEADER = SEP + "MSG: std_msgs/Header\n" + HEADER + SEP + TIME
COMPRESSED = "std_msgs/Header header\nstring format\nuint8[] data\n" + STD_HEADER
IMAGE = ("std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\n"
         "uint8 is_bigendian\nuint32 step\nuint8[] data\n" + STD_HEADER)
NAVSAT = ("std_msgs/Header header\nNavSatStatus status\nfloat64 latitude\nfloat64 longitude\n"
          "float64 altitude\nfloat64[9] position_covariance\nuint8 position_covariance_type\n"
          + STD_HEADER + SEP + "MSG: sensor_msgs/NavSatStatus\nint8 status\nuint16 service\n")
VEC = SEP + "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n"
QUAT = SEP + "MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n"
IMU = ("std_msgs/Header header\ngeometry_msgs/Quaternion orientation\n"
       "float64[9] orientation_covariance\ngeometry_msgs/Vector3 angular_velocity\n"
       "float64[9] angular_velocity_covariance\ngeometry_msgs/Vector3 linear_acceleration\n"
       "float64[9] linear_acceleration_covariance\n" + STD_HEADER + QUAT + VEC)
CAMINFO = ("std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\n"
           "float64[] d\nfloat64[9] k\nfloat64[9] r\nfloat64[12] p\n" + STD_HEADER)


def image_format(name):
    """CompressedImage.format of a drive's image file: `jpeg` or `png`, by its extension."""
    return "jpeg" if name.lower().endswith((".jpg", ".jpeg")) else "png"


def ns_of(text):
    return int(Decimal(text) * 1_000_000_000)


def header(ns, frame_id):
    return {"stamp": {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000},
            "frame_id": frame_id}


def png_gray8(data):
    """Pixels of an 8-bit greyscale non-interlaced PNG (what the simulator writes)."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat, w, h = 8, b"", 0, 0
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        if kind == b"IHDR":
            w, h, depth, color = struct.unpack(">IIBB", body[:10])
            assert (depth, color, body[12]) == (8, 0, 0)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    raw, out, prev = zlib.decompress(idat), bytearray(), bytearray(w)
    for y in range(h):
        f, line = raw[y * (w + 1)], bytearray(raw[y * (w + 1) + 1:(y + 1) * (w + 1)])
        for x in range(w):
            a = line[x - 1] if x else 0
            b, c = prev[x], prev[x - 1] if x else 0
            if f == 1:
                line[x] = (line[x] + a) & 255
            elif f == 2:
                line[x] = (line[x] + b) & 255
            elif f == 3:
                line[x] = (line[x] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[x] = (line[x] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        out += line
        prev = line
    return w, h, bytes(out)


def gnss_epochs(path):
    """(time ns, lat, lon, ellipsoidal height or None) from the simulator's RMC/GGA."""
    out, date = [], None
    for line in Path(path).read_text().splitlines():
        f = line.split("*")[0].split(",")
        if f[0].endswith("RMC"):
            date = f[9]
        elif f[0].endswith("GGA") and date:
            import datetime
            d = datetime.datetime.strptime(date + f[1][:6], "%d%m%y%H%M%S").replace(
                tzinfo=datetime.timezone.utc)
            ns = int(d.timestamp()) * 1_000_000_000 + ns_of("0" + f[1][6:])
            if f[6] == "0":
                out.append((ns, None))
                continue
            lat = (int(f[2][:2]) + Decimal(f[2][2:]) / 60) * (1 if f[3] == "N" else -1)
            lon = (int(f[4][:3]) + Decimal(f[4][3:]) / 60) * (1 if f[5] == "E" else -1)
            out.append((ns, (float(lat), float(lon), float(Decimal(f[9]) + Decimal(f[11])))))
    return out


def navsat(ns, fix):
    lat, lon, alt = fix if fix else (0.0, 0.0, 0.0)
    return {"header": header(ns, "gps"), "status": {"status": 0 if fix else -1, "service": 1},
            "latitude": lat, "longitude": lon, "altitude": alt,
            "position_covariance": [4.0, 0, 0, 0, 4.0, 0, 0, 0, 9.0],
            "position_covariance_type": 2}


def main(src, out, drop=True, raw5=True):
    src, out = Path(src), Path(out)
    frames = list(csv.DictReader(open(src / "frames.csv")))
    truth = {r["frame"]: r for r in csv.DictReader(open(src / "truth.csv"))}
    with open(out / "run.mcap", "wb") as f:
        w = Writer(f, chunk_size=64 * 1024, compression=CompressionType.ZSTD)
        s_comp = w.register_msgdef("sensor_msgs/msg/CompressedImage", COMPRESSED)
        s_img = w.register_msgdef("sensor_msgs/msg/Image", IMAGE)
        s_nav = w.register_msgdef("sensor_msgs/msg/NavSatFix", NAVSAT)
        s_imu = w.register_msgdef("sensor_msgs/msg/Imu", IMU)
        s_info = w.register_msgdef("sensor_msgs/msg/CameraInfo", CAMINFO)
        t0 = ns_of(frames[0]["time_s"])
        w.write_message("/ladybug/cam0/camera_info", s_info, {
            "header": header(t0, "cam0"), "height": 120, "width": 160,
            "distortion_model": "equidistant", "d": [0.0] * 4, "k": [0.0] * 9, "r": [0.0] * 9,
            "p": [0.0] * 12}, log_time=t0)
        epochs = gnss_epochs(src / "gnss.nmea")
        for row in frames:
            t = ns_of(row["time_s"])
            for ns, fix in [e for e in epochs if e[0] <= t]:
                w.write_message("/gps/fix", s_nav, navsat(ns, fix), log_time=ns)
            epochs = [e for e in epochs if e[0] > t]
            q = truth[row["frame"]]
            w.write_message("/imu/data", s_imu, {
                "header": header(t, "imu"),
                "orientation": {k: float(q["q" + k]) for k in "xyzw"},
                "orientation_covariance": [1e-4, 0, 0, 0, 1e-4, 0, 0, 0, 1e-2],
                "angular_velocity": {"x": 0.0, "y": 0.0, "z": 0.01},
                "angular_velocity_covariance": [0.0] * 9,
                "linear_acceleration": {"x": 0.1, "y": 0.0, "z": 9.81},
                "linear_acceleration_covariance": [0.0] * 9}, log_time=t)
            for k in range(6):
                if drop and row["frame"] == "2" and k == 4:
                    continue  # a dropped image
                data = (src / row[f"image_{k}"]).read_bytes()
                stamp = t + k * 1_000_000
                if k < 5 or not raw5:
                    w.write_message(f"/ladybug/cam{k}/image/compressed", s_comp, {
                        "header": header(stamp, f"cam{k}"),
                        "format": image_format(row[f"image_{k}"]), "data": data},
                        log_time=stamp + 5_000_000)
                else:
                    width, height, pixels = png_gray8(data)
                    w.write_message("/ladybug/cam5/image_raw", s_img, {
                        "header": header(stamp, "cam5"), "height": height, "width": width,
                        "encoding": "mono8", "is_bigendian": 0, "step": width, "data": pixels},
                        log_time=stamp + 5_000_000)
        for ns, fix in epochs:
            w.write_message("/gps/fix", s_nav, navsat(ns, fix), log_time=ns)
        w.finish()

    with open(out / "bad.mcap", "wb") as f:
        w = Writer(f, chunk_size=1024, compression=CompressionType.NONE)
        s_comp = w.register_msgdef("sensor_msgs/msg/CompressedImage", COMPRESSED)
        s_nav = w.register_msgdef("sensor_msgs/msg/NavSatFix", NAVSAT)
        t = ns_of(frames[0]["time_s"])
        png = (src / frames[0]["image_0"]).read_bytes()
        w.write_message("/front/image/compressed", s_comp, {
            "header": header(t, "front"), "format": "png", "data": png}, log_time=t)
        w.write_message("/ladybug/cam0/image/compressed", s_comp, {
            "header": header(t, "cam0"), "format": "png", "data": png}, log_time=t)
        w.write_message("/gps/fix", s_nav, navsat(t, None), log_time=t)
        w.write_message("/gps/fix", s_nav, navsat(t + 200_000_000, (37.5, -122.25, 10.0)),
                        log_time=t + 200_000_000)
        s_imu = w.register_msgdef("sensor_msgs/msg/Imu", IMU)
        for q in ({"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},            # good
                  {"x": float("nan"), "y": 0.0, "z": 0.0, "w": 1.0},   # NaN
                  {"x": 0.0, "y": 0.0, "z": 0.0, "w": 0.0}):           # zero quaternion
            w.write_message("/imu/data", s_imu, {
                "header": header(t, "imu"), "orientation": q,
                "orientation_covariance": [1e-4, 0, 0, 0, 1e-4, 0, 0, 0, 1e-2],
                "angular_velocity": {"x": 0.0, "y": 0.0, "z": 0.0},
                "angular_velocity_covariance": [0.0] * 9,
                "linear_acceleration": {"x": 0.0, "y": 0.0, "z": 9.81},
                "linear_acceleration_covariance": [0.0] * 9}, log_time=t)
        raw = w._writer  # the underlying mcap writer, for channels rosbag2 would not write
        json_channel = raw.register_channel("/gps/json", "json", s_nav.id)
        raw.add_message(json_channel, t, b'{"latitude": 1}', t)
        cut_channel = raw.register_channel("/ladybug/cam1/image/compressed", "cdr", s_comp.id)
        raw.add_message(cut_channel, t, b"\x00\x01\x00\x00\x05\x00\x00\x00", t)
        w.finish()


if __name__ == "__main__":
    # `--complete`: keep every image (to compare a replay of the recording with the folder's).
    main(sys.argv[1], sys.argv[2], drop="--complete" not in sys.argv[3:],
         raw5="--all-compressed" not in sys.argv[3:])
