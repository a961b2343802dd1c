#!/usr/bin/env python3
"""The session result JSON (doc/session_result.md) for Python: the same contract as the C++ reader
(vrm_sim/result/session_result.h). Required: "scene" (non-empty string), "final_state_hash" (string), "frames"
(non-negative integer); every other key may be absent or null (null numbers read as NaN); a present key of the wrong
type, or text that is not one JSON object (truncated, NaN written as nan), raises ResultError naming the source and
the key. Unknown keys are kept (a newer writer's fields), not refused.

Usage as a tool: session_result.py RESULT.json [KEY...] prints the result's keys (or the given ones, one per line);
exit 1 on a malformed result."""
import json
import math
import sys

NAN = float("nan")


class ResultError(ValueError):
    """A malformed result: the message names the source and the key."""


# key -> (type, default when absent). "number" is int or float; null numbers read as NaN, other nulls as None.
SCHEMA = {
    "scene": ("string", None),
    "scene_file": ("string", ""),
    "scenario": ("string", None),
    "difficulty": ("string", None),
    "seed": ("count", 0),
    "state": ("string", None),
    "session_ended": ("bool", False),
    "timed_out": ("bool", False),
    "message": ("string", ""),
    "start_stamp": ("number", 0.0),
    "end_stamp": ("number", 0.0),
    "elapsed": ("number", NAN),
    "total": ("number", NAN),
    "items": ("items", []),
    "groups": ("groups", []),
    "events": ("events", []),
    "events_dropped": ("count", 0),
    "final_state_hash": ("string", None),
    "frames": ("count", 0),
    "simulated_frames": ("count", 0),
    "late_inputs": ("count", 0),
    "frames_without_source": ("count", 0),
    "input_frames": ("count", 0),
    "last_frame_stamp": ("number", 0.0),
    "software_version": ("string", ""),
    "bag": ("string", None),
    "user": ("string", None),
    "station": ("string", ""),
    "in_progress": ("bool", False),
    "interrupted": ("bool", False),
}
REQUIRED = ("scene", "final_state_hash", "frames")
ITEM_SCHEMA = {
    "name": ("string", None),
    "value": ("number", NAN),
    "unit": ("string", ""),
    "weight": ("number", 0.0),
    "points": ("number", NAN),
}
GROUP_SCHEMA = {
    "name": ("string", None),
    "points": ("number", NAN),
    "weight": ("number", 0.0),
}
EVENT_SCHEMA = {
    "time": ("number", NAN),
    "kind": ("string", None),
    "item": ("string", ""),
    "slot": ("string", ""),
    "instrument": ("string", ""),
    "position": ("position", [NAN, NAN, NAN]),
    "points": ("number", NAN),
}
# The rows of an array key, and the key of each row that must be a non-empty string.
ROWS = {"items": (ITEM_SCHEMA, "name"), "groups": (GROUP_SCHEMA, "name"), "events": (EVENT_SCHEMA, "kind")}
MAX_SEED = 2**32 - 1
MAX_COUNT = 2**63 - 1


def _refuse_constant(name):
    # Python's json reads NaN / Infinity / -Infinity; JSON (and the C++ reader) does not.
    raise ValueError(f"{name} is not JSON")


def _finite_float(text):
    # Python reads 1e400 as infinity; the C++ reader (nlohmann) refuses a number beyond a double.
    value = float(text)
    if math.isinf(value):
        raise ValueError(f"number overflow parsing '{text}'")
    return value


def _integer(text):
    # Integers beyond 64 bits are doubles in the C++ reader, and one beyond a double is refused there too.
    value = int(text)
    return value if -(2**63) <= value < 2**64 else _finite_float(text)


def _field(obj, key, kind, default, source, where=""):
    def fail(what):
        raise ResultError(f'{source}: result field {where}"{key}" {what}')

    if key not in obj:
        return default
    value = obj[key]
    if value is None:
        if kind == "position":
            return list(default)
        return NAN if kind == "number" else (default if kind in ("bool", "count") or kind in ROWS else None)
    if kind == "string":
        if not isinstance(value, str):
            fail("is not a string")
    elif kind == "bool":
        if not isinstance(value, bool):
            fail("is not true or false")
    elif kind == "number":
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            fail("is not a number")
        value = float(value)
    elif kind == "count":
        limit = MAX_SEED if key == "seed" else MAX_COUNT
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            fail("is not a number")
        if isinstance(value, float):
            if not value.is_integer():
                fail("is not a non-negative integer in range")
            value = int(value)  # 7.0 written by a float formatter is still a count
        if value < 0:
            fail("is not a non-negative integer in range")
        if value > limit:
            fail("is out of range")
    elif kind == "position":
        if not isinstance(value, list) or len(value) != 3:
            fail("is not an array of 3")
        for coordinate in value:
            if coordinate is not None and (isinstance(coordinate, bool) or not isinstance(coordinate, (int, float))):
                fail("has an element that is not a number or null")
        value = [NAN if coordinate is None else float(coordinate) for coordinate in value]
    elif kind in ROWS:
        schema, name_key = ROWS[kind]
        if not isinstance(value, list):
            fail("is not an array")
        rows = []
        for i, row in enumerate(value):
            if not isinstance(row, dict):
                fail(f"has an element that is not an object ({key}[{i}].)")
            entry = {k: _field(row, k, t, d, source, f"{key}[{i}].") for k, (t, d) in schema.items()}
            if not entry[name_key]:
                raise ResultError(f'{source}: result field {key}[{i}]."{name_key}" is missing or empty')
            rows.append(entry)
        value = rows
    return value


def from_json(text, source):
    """The result in `text` as a dict with every schema key (absent ones at their defaults)."""
    try:
        root = json.loads(text, parse_constant=_refuse_constant, parse_float=_finite_float, parse_int=_integer)
    except ValueError as error:
        raise ResultError(f"{source}: malformed result JSON: {error}") from None
    if not isinstance(root, dict):
        raise ResultError(f"{source}: the result JSON is not an object")
    for key in REQUIRED:
        if key not in root:
            raise ResultError(f'{source}: result field "{key}" is missing (required)')
        if root[key] is None or root[key] == "":
            raise ResultError(f'{source}: result field "{key}" is null or empty (required)')
    result = dict(root)  # unknown keys kept as they are
    for key, (kind, default) in SCHEMA.items():
        result[key] = _field(root, key, kind, default, source)
    return result


def read(path):
    """The result file at `path` (ResultError naming the path if it cannot be read or is malformed)."""
    try:
        with open(path, encoding="utf-8") as handle:
            text = handle.read()
    except (OSError, UnicodeDecodeError) as error:
        raise ResultError(f"{path}: cannot read the result file: {error}") from None
    return from_json(text, path)


def is_unknown(value):
    """True for a number the result does not know (written null: NaN)."""
    return isinstance(value, float) and math.isnan(value)


def main(argv):
    if len(argv) < 2 or argv[1] in ("-h", "--help"):
        print(__doc__)
        return 0 if len(argv) >= 2 else 2
    try:
        result = read(argv[1])
    except ResultError as error:
        print(f"session_result.py: {error}", file=sys.stderr)
        return 1
    keys = argv[2:] or list(result.keys())
    for key in keys:
        if key not in result:
            print(f"session_result.py: {argv[1]} has no key '{key}'", file=sys.stderr)
            return 1
        print(result[key] if argv[2:] else f"{key}: {result[key]}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
