#!/usr/bin/env python3
"""Writes the seed corpora of the fuzz targets (corpus/<target>/) from the shipped files: scenes, meshes, scripts,
rig and layout YAML, the reference session bags (their messages, and short bags cut from them), plus synthetic
marker images and marker observations projected through the default rig. Run from anywhere; needs the vrm_msgs
Python messages of a built workspace on PYTHONPATH (scripts/fuzz.sh sets it). Deterministic: same files, same seeds.

Also writes libFuzzer dictionaries for the text formats (dict/<target>.dict, passed by scripts/fuzz.sh as -dict): the
names the strict readers ask for (every identifier-like string literal of the reader's sources: keys, enum names),
the keys and words of the target's seeds, and the format's own syntax, so mutations insert whole keys and names.

Usage: make_seeds.py [--check]   (--check: exit 1 if a seed or dictionary would change, write nothing)"""
import io
import re
import pathlib
import shutil
import struct
import sys

import rosbag
import yaml

import vrm_msgs.msg as vm

PKG = pathlib.Path(__file__).resolve().parent.parent
SRC = PKG.parent
SIM = SRC / "vrm_sim"
TRK = SRC / "vrm_tracking"
SCENE_DATA = SRC / "vrm_scene" / "test" / "data"  # the floor's test scenes and meshes (issue 42)
CORPUS = PKG / "corpus"
seeds = {}  # path -> bytes


def seed(target, name, data):
    seeds[CORPUS / target / name] = bytes(data)


def ser(msg):
    b = io.BytesIO()
    msg.serialize(b)
    return b.getvalue()


def frame(kind, payload):
    return struct.pack("<BH", kind, len(payload)) + payload


def ros_string(s):
    s = s.encode()
    return struct.pack("<I", len(s)) + s


def camera_info(width, height, K, D):
    header = struct.pack("<III", 0, 0, 0) + ros_string("camera_0")
    out = header + struct.pack("<II", height, width) + ros_string("plumb_bob")
    out += struct.pack("<I", len(D)) + struct.pack("<%dd" % len(D), *D)
    out += struct.pack("<9d", *K) + struct.pack("<9d", 1, 0, 0, 0, 1, 0, 0, 0, 1)
    out += struct.pack("<12d", K[0], 0, K[2], 0, 0, K[4], K[5], 0, 0, 0, 1, 0)
    out += struct.pack("<II", 0, 0) + struct.pack("<IIIIB", 0, 0, 0, 0, 0)
    return out


# --- files ---
for p in sorted((SIM / "config" / "scenes").glob("*.yaml")) + sorted((SCENE_DATA / "scenes").glob("*.yaml")):
    seed("scene_yaml", p.parent.parent.name + "_" + p.name if "test" in p.parts else p.name, p.read_bytes())
ext = {".obj": 0, ".ply": 1, ".stl": 2}
for p in sorted((SCENE_DATA / "meshes").iterdir()):
    if p.suffix in ext:
        seed("mesh_import", p.name, bytes([ext[p.suffix], 1]) + p.read_bytes())
# The one scripted-motion format (issue 34): the shipped script files, and a scene's short form.
for p in sorted((SIM / "config" / "scripts").glob("*.yaml")):
    seed("surgeon_script", p.name, p.read_bytes())
seed("surgeon_script", "exchange_and_target.yaml",
     b"playback: loop\nmissing_objects: keep_tip\ninstruments:\n  - slot: right\n    path:\n"
     b"      - {t: 0, tip: [0.001, 0, -0.006], jaw_angle_deg: 20}\n"
     b"      - {t: 1, on: membrane, tip: [0.003, 0.001, -0.011], height: -6.0e-5, type: vitrector}\n"
     b"    tremor: {amplitude: 2.0e-5, frequency_hz: 10}\neye: [{t: 0, rpy_deg: [1, 2, 3]}]\n")
seed("rig_yaml", "rig_default.yaml", (TRK / "config" / "rig_default.yaml").read_bytes())
seed("marker_layout_yaml", "markers_default.yaml", (TRK / "config" / "markers_default.yaml").read_bytes())
# The strict reader's error paths (vrm_scene/yaml/strict_reader.h): a misspelt key, an unknown class name, a duplicate
# slot, a matrix of the wrong shape; the fuzzer mutates from each.
seed("marker_layout_yaml", "typo_key.yaml", b"eye_marker_radius: 0.0005\ntip_marker_radus: 0.0004\n")
seed("marker_layout_yaml", "unknown_class.yaml", b"instruments:\n  - {slot: left, class: tip_lft}\n")
seed("marker_layout_yaml", "duplicate_slot.yaml",
     b"instruments:\n  - {slot: left, class: tip_left}\n  - {slot: left, class: tip_right}\n")
seed("rig_yaml", "typo_key.yaml", b"cameras:\n  - image_width: 640\n    image_height: 480\n"
     b"    camera_matrix: [800, 0, 320, 0, 800, 240, 0, 0, 1]\n    camera_nmae: cam0\n")
seed("rig_yaml", "matrix_shape.yaml", b"cameras:\n  - image_width: 640\n    image_height: 480\n"
     b"    camera_matrix: {rows: 3, cols: 4, data: [800, 0, 320, 0, 800, 240, 0, 0, 1]}\n")
rig = yaml.safe_load((TRK / "config" / "rig_default.yaml").read_text())
for i, cam in enumerate(rig["cameras"]):
    seed("camera_yaml", "camera_%d.yaml" % i, yaml.safe_dump(cam, sort_keys=False).encode())

# --- marker images: [u16 w][u16 h][u8 enc][u8 flags][i16 x4 region][u8 class][f64 u v r] pixels ---
layout = yaml.safe_load((TRK / "config" / "markers_default.yaml").read_text())
colours = [c["bgr"] for c in layout["classes"]]


def image(w, h, blobs, enc=0, flags=0):
    px = bytearray()
    for y in range(h):
        for x in range(w):
            c = [90, 90, 90]
            for (bx, by, r, col) in blobs:
                if (x - bx) ** 2 + (y - by) ** 2 <= r * r:
                    c = col
            px += bytes(c if enc == 0 else (c[::-1]))
    head = struct.pack("<HHBBhhhhB3d", w, h, enc, flags, 0, 0, w, h, 0, w / 2, h / 2, 3.0)
    return head + px


seed("marker_detector", "four_markers_bgr8", image(48, 40, [(10, 10, 3, colours[0]), (30, 12, 3, colours[1]),
                                                         (12, 30, 3, colours[2]), (36, 30, 4, colours[3])]))
seed("marker_detector", "two_markers_rgb8", image(32, 24, [(8, 8, 3, colours[2]), (22, 14, 3, colours[3])], enc=1))
seed("marker_detector", "grey_bgra8", struct.pack("<HHBBhhhhB3d", 16, 8, 2, 0, -4, -4, 40, 40, 1, 1.0, 1.0, 2.0) +
     bytes([90, 90, 90, 255]))

# --- calibrator images: [u8 role][u8 encoding][u16 w][u16 h] pixels (fuzz/calibrator_images.cpp) ---
# A 5 x 4 inner-corner chessboard (6 x 5 squares, the first black, a one-square white border on grey) seen through
# three homographies and on the fixture, 96 x 80 mono8, 2 x 2 supersampled.
import math


def board_grey(u, v):
    if u < -1 or u >= 7 or v < -1 or v >= 6:
        return 110
    if u < 0 or u >= 6 or v < 0 or v >= 5:
        return 255
    return 0 if (math.floor(u) + math.floor(v)) % 2 == 0 else 255


def board_image(w, h, hom):  # hom: pixel -> board squares (3 x 3, row-major)
    out = bytearray()
    for y in range(h):
        for x in range(w):
            acc = 0
            for sy in (0.25, 0.75):
                for sx in (0.25, 0.75):
                    px, py = x + sx, y + sy
                    d = hom[6] * px + hom[7] * py + hom[8]
                    acc += board_grey((hom[0] * px + hom[1] * py + hom[2]) / d, (hom[3] * px + hom[4] * py + hom[5]) / d)
            out.append(acc // 4)
    return bytes(out)


def board_pose(scale, angle, tx, ty, px, py):
    c, s = math.cos(angle), math.sin(angle)
    return [c / scale, s / scale, tx, -s / scale, c / scale, ty, px, py, 1.0]


BW, BH = 96, 80
board_views = [board_pose(10.0, 0.05, -1.6, -1.4, 0.0008, 0.0), board_pose(9.0, -0.12, -1.4, -0.8, -0.0006, 0.0009),
               board_pose(9.0, 0.3, -2.4, -1.0, 0.0, -0.0012)]
board_fixture = board_pose(10.0, 0.0, -1.8, -1.5, 0.0, 0.0)


def calibrator_image(role, pixels, w=BW, h=BH, encoding=0, flags=0):  # encoding 0: mono8 (calibrator_images.cpp)
    return struct.pack("<BBBHH", role, encoding, flags, w, h) + pixels


views = [board_image(BW, BH, v) for v in board_views]
seed("calibrator_images", "chessboard_three_views_and_fixture",
     b"".join(calibrator_image(0, v) for v in views) + calibrator_image(1, board_image(BW, BH, board_fixture)))
seed("calibrator_images", "one_view_bgr8",
     calibrator_image(0, bytes(b for p in views[0] for b in (p, p, p)), encoding=1))
seed("calibrator_images", "unknown_encoding_short",
     calibrator_image(0, bytes(range(40)), 17, 9, encoding=8, flags=0x41))


# The collector's and the detector's other paths, which the fuzzer did not find from the seeds above in 220,000
# executions (coverage 784 vs 789: a calibration needs three distinct boards and a fixture in one input). Each seed
# stays under the target's 32 KB max_len, so at most four 96 x 80 images.
def invert3(m):
    a, b, c, d, e, f, g, hh, i = m
    det = a * (e * i - f * hh) - b * (d * i - f * g) + c * (d * hh - e * g)
    return [(e * i - f * hh) / det, (c * hh - b * i) / det, (b * f - c * e) / det,
            (f * g - d * i) / det, (a * i - c * g) / det, (c * d - a * f) / det,
            (d * hh - e * g) / det, (b * g - a * hh) / det, (a * e - b * d) / det]


def light_end_squares(pixels, hom, w=BW, h=BH):
    """The board with a white spot in the squares detectTarget may sample at either end of OpenCV's corner order (the
    corner squares inside the inner corners, in either row order): corners found, no dark first square."""
    out = bytearray(pixels)
    inv = invert3(hom)
    for u, v in ((1.5, 1.5), (4.5, 3.5), (1.5, 3.5), (4.5, 1.5)):
        d = inv[6] * u + inv[7] * v + inv[8]
        cx, cy = (inv[0] * u + inv[1] * v + inv[2]) / d, (inv[3] * u + inv[4] * v + inv[5]) / d
        for y in range(round(cy) - 1, round(cy) + 2):
            for x in range(round(cx) - 1, round(cx) + 2):
                if 0 <= x < w and 0 <= y < h:
                    out[y * w + x] = 255
    return bytes(out)


fourth_view = board_image(BW, BH, board_pose(9.5, -0.35, -1.2, -1.9, 0.0007, 0.0007))
blank = bytes([110]) * (16 * 16)
seed("calibrator_images", "light_end_squares", calibrator_image(0, light_end_squares(views[0], board_views[0])))
# The same pose twice, then a view of another size.
seed("calibrator_images", "same_pose_and_other_size",
     b"".join(calibrator_image(0, v) for v in (views[0], views[0])) +
     calibrator_image(0, board_image(80, 64, board_views[1]), 80, 64))
# A fourth view once three are in, an empty fixture.
seed("calibrator_images", "fourth_view_and_empty_fixture",
     b"".join(calibrator_image(0, v) for v in views[1:] + [views[0], fourth_view]) + calibrator_image(1, b"", 0, 0))
# A fixture without a board (the extrinsic step fails), then a view and a fixture after the one attempt.
seed("calibrator_images", "blank_fixture_then_more",
     b"".join(calibrator_image(0, v) for v in views) +
     b"".join(calibrator_image(role, blank, 16, 16) for role in (1, 0, 1)))

# --- messages of the reference bags (vrm_sim topics) ---
def first_messages_bag(bag, path, count, **options):
    """The bytes of a bag holding `bag`'s first `count` messages (written through `path`, removed again)."""
    with rosbag.Bag(str(path), "w", **options) as out:
        for n, (topic, raw, t) in enumerate(bag.read_messages(raw=True)):
            if n >= count:
                break
            out.write(topic, raw, t, raw=True)
    data = path.read_bytes()
    path.unlink()
    return data


KIND = {"/eye_state": 0, "/instrument_state": 1, "/pedals": 2, "/scenario_command": 3, "/microscope": 4,
        "/session_info": 5}
for bag_name, scene_index in (("navigation_expert", 0), ("membrane_peeling_novice", 1), ("vitrectomy_expert", 2)):
    with rosbag.Bag(str(SIM / "test" / "bags" / (bag_name + ".bag"))) as bag:
        frames = []
        for topic, raw, _ in bag.read_messages(raw=True):
            if topic in KIND and len(frames) < 40:
                frames.append(frame(KIND[topic], raw[1]))
        seed("sim_messages", bag_name, bytes([scene_index]) + b"".join(frames))
        seed("sim_conversions", bag_name, bytes([scene_index]) + b"".join(frames))
        # A short bag of the first messages (and a cut-off copy, which only recovery can read); of one reference bag
        # the same messages in small compressed chunks too, which the structure check and recovery decompress.
        first24 = first_messages_bag(bag, PKG / ("_tmp_%s.bag" % bag_name), 24)
        seed("session_bag", bag_name + "_first24", first24)
        seed("session_bag", bag_name + "_first24_cut", first24[: len(first24) * 2 // 3])
        if bag_name == "navigation_expert":
            for compression in ("bz2", "lz4"):
                seed("session_bag", bag_name + "_first24_" + compression,
                     first_messages_bag(bag, PKG / ("_tmp_%s.bag" % bag_name), 24, compression=compression,
                                        chunk_threshold=4096))

mesh = vm.TissueMesh()
mesh.tissue_id = "membrane"
mesh.positions = [0, 0, 0, 0.001, 0, 0, 0, 0.001, 0]
mesh.triangles = [0, 1, 2]
settings = vm.MicroscopeSettings(focus_distance=0.2, zoom=1.5, ambient_light=0.5, disparity_scale=1.0)
seed("sim_messages", "tissue_mesh_and_microscope", bytes([0]) + frame(6, ser(mesh)) + frame(4, ser(settings)))
seed("sim_conversions", "tissue_mesh_and_microscope", bytes([0]) + frame(6, ser(mesh)) + frame(4, ser(settings)))

# --- tracking: marker observations projected through the default rig ---
import math


def project(cam, p):
    R = cam["world_to_camera"]["rotation"]["data"]
    t = cam["world_to_camera"]["translation"]
    K = cam["camera_matrix"]["data"]
    c = [sum(R[3 * i + j] * p[j] for j in range(3)) + t[i] for i in range(3)]
    return K[0] * c[0] / c[2] + K[2], K[4] * c[1] / c[2] + K[5]


points = [m["position"] for m in layout["eye_markers"]] + [[-0.002, 0.001, -0.004], [0.002, 0.001, -0.004]]
frames = []
for stamp in range(3):
    for ci, cam in enumerate(rig["cameras"]):
        obs = vm.MarkerObservations()
        obs.header.stamp.secs = 100
        obs.header.stamp.nsecs = stamp * 20000000
        obs.camera_name = cam["camera_name"]
        obs.image_width, obs.image_height = cam["image_width"], cam["image_height"]
        for cls, p in enumerate(points):
            u, v = project(cam, p)
            obs.markers.append(vm.MarkerObservation(class_id=cls, u=u, v=v, area=30.0, quality=0.9))
        frames.append(frame(8 * ci, ser(obs)))
sensors = vm.InstrumentState(instrument_id="left", type=1, jaw_angle=0.3, valid=True)
sensors.tip_pose.orientation.w = 1.0
frames.append(frame(2, ser(sensors)))
eye = vm.EyeState(valid=True)
eye.rotation.w = 1.0
frames.append(frame(3, ser(eye)))
cam0 = rig["cameras"][0]
frames.append(frame(4, camera_info(640, 480, cam0["camera_matrix"]["data"], [0, 0, 0, 0, 0])))
frames.append(frame(5, ser(vm.PedalState(zoom_in=True))))
frames.append(frame(6, ser(settings)))
timing = vm.StageTiming()
timing.header.stamp.secs = 100
for name, a, b in (("camera", 0, 1), ("detection_camera_0", 1, 3), ("reconstruction", 3, 4), ("simulation", 4, 9)):
    st = vm.StageStamp(stage=name)
    st.start.secs = st.end.secs = 100
    st.start.nsecs, st.end.nsecs = a * 1000000, b * 1000000
    timing.stages.append(st)
frames.append(frame(7, ser(timing)))
seed("tracking_messages", "three_camera_frames", bytes([0]) + b"".join(frames))
seed("tracking_messages", "one_euro_filter", bytes([1]) + b"".join(frames))

# --- mesh upload (fuzz/mesh_upload.cpp): kind % 8 = 0 mesh, 1 pose, 2 microscope, 3 burns, 4 light pipe, 5 visibility,
# 6 style, 7 render; kind bits 3-4 pick the object (0 membrane, 1 retina, 2 instrument, 3 ghost) ---
def grid_mesh(n, size, z, version):
    m = vm.TissueMesh(tissue_id="membrane", version=version, topology_version=1)
    m.header.frame_id = "eye"
    for j in range(n):
        for i in range(n):
            m.positions += [(i / (n - 1) - 0.5) * size, (j / (n - 1) - 0.5) * size, z]
            m.colors += [0.9, 0.8, 0.7, 0.6]
            m.injury += [(i + j) / (2.0 * n)]
    for j in range(n - 1):
        for i in range(n - 1):
            a = j * n + i
            m.triangles += [a, a + 1, a + n, a + 1, a + n + 1, a + n]
    return m


def pose(x, y, z):
    p = vm.InstrumentState().tip_pose
    p.position.x, p.position.y, p.position.z = x, y, z
    p.orientation.w = 1.0
    return p


burns = vm.SimulationState()
for k in range(3):
    b = vm.LaserBurn(diameter=0.0004, whiteness=0.8)
    b.position.x, b.position.y, b.position.z = 0.001 * k, 0.0005, -0.011
    burns.burns.append(b)
upload = (frame(0, ser(grid_mesh(6, 0.004, -0.008, 1))) + frame(8, ser(grid_mesh(8, 0.02, -0.012, 1))) +
          frame(16, ser(grid_mesh(3, 0.002, -0.004, 1))) + frame(17, ser(pose(0.0, 0.0, 0.002))) +
          frame(2, ser(settings)) + frame(3, ser(burns)) + frame(4 | 0x80, ser(pose(0.001, 0.0, -0.002))) +
          frame(7, b"") + frame(0, ser(grid_mesh(6, 0.004, -0.007, 2))) + frame(24 | 6, bytes([0x30])) +
          frame(24, ser(grid_mesh(3, 0.002, -0.003, 1))) + frame(5 | 0x20, b"") + frame(7, b""))
seed("mesh_upload", "membrane_retina_instrument_rendered", upload)
seed("mesh_upload", "mesh_replaced_then_removed", frame(0, ser(grid_mesh(4, 0.003, -0.008, 1))) +
     frame(0, ser(grid_mesh(5, 0.003, -0.008, 2))) + frame(5 | 0x80, b"") + frame(7, b""))

# --- dictionaries for the text formats ---
DICT = PKG / "dict"
SCENE_SRC = SRC / "vrm_scene" / "src" / "scene"
READERS = {  # target -> the sources of the reader it drives
    "camera_yaml": [TRK / "src" / "core" / "camera_rig.cpp"],
    "rig_yaml": [TRK / "src" / "core" / "camera_rig.cpp"],
    "marker_layout_yaml": [TRK / "src" / "core" / "marker_layout.cpp"],
    "scene_yaml": sorted(SCENE_SRC.glob("*.cpp")),
    "surgeon_script": [SCENE_SRC / "scene_loader.cpp"],
    "session_result_json": [SIM / "src" / "core" / "result" / "session_result.cpp"],
}
YAML_SYNTAX = [": ", "- ", "\n  - ", "[", "]", "{", "}", ", ", "~", "null", "true", "false", "yes", "no", ".inf",
               "-.inf", ".nan", "0x", "1e308", "-1e-308", "&a ", "*a", "<<: ", "!!str ", "!!int ", "!!float ", "!!map ",
               "!!seq ", "---", "...", "|", ">", "'", "#", "? "]
JSON_SYNTAX = ['": ', '"', "[", "]", "{", "}", ", ", "null", "true", "false", "1e308", "-0", "\\u0000", "\\ud800"]


def words_of(value, out):
    """Keys and string scalars of a parsed YAML/JSON document."""
    if isinstance(value, dict):
        for k, v in value.items():
            out.add(str(k))
            words_of(v, out)
    elif isinstance(value, list):
        for v in value:
            words_of(v, out)
    elif isinstance(value, str) and len(value) <= 40:
        out.add(value)


def dict_entry(word):
    escaped = "".join(c if 0x20 <= ord(c) < 0x7f and c not in '"\\' else "\\x%02X" % ord(c)
                      for c in word.encode("utf-8", "surrogateescape").decode("latin-1"))
    return '"%s"' % escaped


dictionaries = {}
for target, sources in READERS.items():
    words = set()
    for source in sources:
        words.update(re.findall(r'"([a-z][a-z0-9_]{1,40})"', source.read_text()))
    for path, data in seeds.items():
        if path.parent.name != target:
            continue
        try:
            words_of(yaml.safe_load(data.decode("utf-8")), words)
        except Exception:  # the seeds of error paths are malformed on purpose
            pass
    syntax = JSON_SYNTAX if target.endswith("_json") else YAML_SYNTAX
    lines = ["# libFuzzer dictionary for fuzz_%s, written by scripts/make_seeds.py: do not edit." % target]
    lines += [dict_entry(w) for w in sorted(words)] + [dict_entry(w) for w in syntax]
    dictionaries[DICT / ("%s.dict" % target)] = ("\n".join(lines) + "\n").encode()
seeds.update(dictionaries)

check = "--check" in sys.argv
changed = [p for p, d in seeds.items() if not p.exists() or p.read_bytes() != d]
if check:
    print("\n".join(str(p) for p in changed) or "seeds up to date")
    sys.exit(1 if changed else 0)
for p, d in seeds.items():
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_bytes(d)
print("%d seeds in %s and %d dictionaries in %s (%d written)" % (len(seeds) - len(dictionaries), CORPUS,
                                                                   len(dictionaries), DICT, len(changed)))
