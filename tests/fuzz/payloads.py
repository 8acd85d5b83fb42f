"""Families of bad input for the fuzz suite, each built from a valid file and broken one way or several.

Byte level (any file): empty, truncated, invalid UTF-8, a byte-order mark, NUL bytes, random bytes. JSON: nesting
far beyond any schema, integers of thousands of digits, duplicate keys, NaN/inf literals, values of every type in
every key. NPZ: wrong dtypes and shapes, missing and unknown keys, absurd values, a lone .npy, archives whose
members declare gigabytes (zip bombs), huge .npy headers, hundreds of members, pickled objects. YAML: the same
byte-level families plus duplicate keys, alias bombs, deep nesting, unsafe tags and include tricks.
"""

from __future__ import annotations

import io
import json
import math
import warnings
import zipfile

import numpy as np
from hypothesis import strategies as st

JOINTS = [f"joint{i}" for i in range(1, 8)]
HOME = [0.0, -0.35, 0.0, 0.55, 0.0, 0.9, 0.0]  # inside every joint's limits

ABSURD_FLOATS = [1e300, -1e300, 1.7e308, -1.7e308, 1e38, 5e-324, -0.0, 1e-300, 3.4e38]
extreme_floats = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from(ABSURD_FLOATS))
json_scalars = st.one_of(st.none(), st.booleans(), st.integers(-(10**30), 10**30), extreme_floats, st.text(max_size=12))
json_values = st.recursive(
    json_scalars,
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4),
    max_leaves=12,
)


def dumps(doc) -> bytes:
    return json.dumps(doc, allow_nan=True).encode()


# -- byte-level corruption ----------------------------------------------------------------------------------
@st.composite
def corrupted(draw, data: bytes) -> bytes:
    """data broken at the byte level in one of the families above."""
    kind = draw(st.sampled_from(["truncate", "utf8", "bom", "nul", "empty", "random", "splice"]))
    at = draw(st.integers(0, len(data)))
    if kind == "truncate":
        return data[:at]
    if kind == "utf8":
        return (
            data[:at] + draw(st.sampled_from([b"\xff", b"\xfe\xff", b"\xc3\x28", b"\xed\xa0\x80", b"\x80"])) + data[at:]
        )
    if kind == "bom":
        return b"\xef\xbb\xbf" + data
    if kind == "nul":
        return data[:at] + b"\x00" + data[at:]
    if kind == "empty":
        return b""
    if kind == "random":
        return draw(st.binary(max_size=300))
    return data[:at] + draw(st.binary(min_size=1, max_size=40)) + data[at:]


@st.composite
def json_text_attacks(draw, data: bytes) -> bytes:
    """JSON-specific: deep nesting, thousands of digits, duplicate keys, a huge string."""
    kind = draw(st.sampled_from(["deep", "digits", "duplicate", "bigstring", "wrapped"]))
    if kind == "deep":
        depth = draw(st.sampled_from([33, 1000, 100_000]))
        return b"[" * depth + data + b"]" * depth
    if kind == "digits":
        digits = draw(st.sampled_from([41, 400, 5000, 100_000]))
        return data.replace(b"0.004", b"9" * digits, 1) if b"0.004" in data else b"9" * digits
    if kind == "duplicate" and data.startswith(b"{"):
        return b'{"dt": 0.004, ' + data[1:]
    if kind == "bigstring":
        return b'{"joint_names": "' + b"x" * 5_000_000 + b'"}'
    return b'{"positions": ' + data + b"}"


# -- trajectories -------------------------------------------------------------------------------------------
def valid_trajectory(steps: list[list[float]] | None = None, dt: float = 0.004) -> dict:
    rows = [list(HOME)] + [[h + d for h, d in zip(HOME, s, strict=True)] for s in (steps or [])]
    return {"joint_names": JOINTS, "dt": dt, "positions": rows}


@st.composite
def trajectory_files(draw) -> bytes:
    """A TRAJ.json: a small valid one, then values of every type and magnitude in its keys, and byte attacks."""
    steps = draw(st.lists(st.lists(st.floats(-0.01, 0.01), min_size=7, max_size=7), max_size=6))
    doc = valid_trajectory(steps)
    rows = doc["positions"]
    mutation = draw(st.sampled_from(["element", "dt", "row", "key", "drop", "events", "jump", "none"]))
    if mutation == "element":
        rows[draw(st.integers(0, len(rows) - 1))][draw(st.integers(0, 6))] = draw(json_values)
    elif mutation == "dt":
        doc["dt"] = draw(json_values)
    elif mutation == "row":
        rows[draw(st.integers(0, len(rows) - 1))] = draw(json_values)
    elif mutation == "key":
        doc[draw(st.sampled_from(["joint_names", "positions", "gripper_events", "extra"]))] = draw(json_values)
    elif mutation == "drop":
        del doc[draw(st.sampled_from(list(doc)))]
    elif mutation == "events":
        event = {"time_s": draw(extreme_floats), "kind": draw(st.sampled_from(["open", "close", "wait", "x"]))}
        doc["gripper_events"] = [event, {"width_m": draw(extreme_floats), "kind": "open", "time_s": 0.0}]
    elif mutation == "jump":
        rows.append([h + draw(st.sampled_from([*ABSURD_FLOATS, 1e6, -1e6, 50.0])) for h in HOME])
    data = dumps(doc)
    layer = draw(st.sampled_from(["none", "bytes", "json"]))
    if layer == "bytes":
        data = draw(corrupted(data))
    elif layer == "json":
        data = draw(json_text_attacks(data))
    return data


@st.composite
def world_files(draw) -> bytes:
    """A WORLD.json with shapes whose numbers are absurd, of the wrong type or too many, and byte attacks."""
    box = {"name": "b", "center": [0.5, 0.0, 0.2], "size": [0.1, 0.1, 0.1], "rpy": [0.0, 0.0, 0.0]}
    doc: dict = {"boxes": [box], "spheres": [{"center": [0.4, 0.3, 0.3], "radius": 0.05}]}
    mutation = draw(st.sampled_from(["box", "many", "held", "width", "key", "points", "none"]))
    if mutation == "box":
        box[draw(st.sampled_from(["center", "size", "rpy", "name"]))] = draw(
            st.one_of(json_values, st.lists(extreme_floats, min_size=3, max_size=3))
        )
    elif mutation == "many":
        doc["boxes"] = [box] * draw(st.sampled_from([1001, 20_000]))
    elif mutation == "held":
        doc["held_object"] = {"kind": draw(st.sampled_from(["box", "sphere", "x"])), "size": draw(json_values)}
    elif mutation == "width":
        doc["gripper_width_m"] = draw(extreme_floats)
    elif mutation == "key":
        doc[draw(st.text(max_size=10))] = draw(json_values)
    elif mutation == "points":
        doc["points_file"] = draw(st.one_of(json_values, st.sampled_from(["", "\x00", "/dev/zero", ".", "~nobody/x"])))
    data = dumps(doc)
    if draw(st.booleans()):
        data = draw(st.one_of(corrupted(data), json_text_attacks(data)))
    return data


# -- npz archives -------------------------------------------------------------------------------------------
def npz_bytes(arrays: dict[str, np.ndarray], compressed: bool = False) -> bytes:
    buf = io.BytesIO()
    (np.savez_compressed if compressed else np.savez)(buf, allow_pickle=True, **arrays)
    return buf.getvalue()


def declared_npz(members: dict[str, tuple[str, tuple[int, ...]]], payload_bytes: int = 1 << 16) -> bytes:
    """An archive whose members only declare (dtype, shape) in their .npy header, followed by payload_bytes of
    zeros, deflated: a few kilobytes on disk that would unpack into whatever the headers claim (a zip bomb)."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        for key, (descr, shape) in members.items():
            with zf.open(f"{key}.npy", "w", force_zip64=True) as f:
                np.lib.format.write_array_header_1_0(f, {"descr": descr, "fortran_order": False, "shape": shape})
                f.write(bytes(payload_bytes))
    return buf.getvalue()


def many_members_npz(n: int) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        for i in range(n):
            zf.writestr(f"a{i}.npy", b"")
    return buf.getvalue()


def encrypted_npz(arrays: dict[str, np.ndarray]) -> bytes:
    """A valid archive with its first member flagged as encrypted (zipfile then wants a password)."""
    data = bytearray(npz_bytes(arrays))
    data[6] |= 1  # general-purpose flag of the first local header
    data[data.find(b"PK\x01\x02") + 8] |= 1  # and of its central directory entry
    return bytes(data)


def repeated_member_npz(key: str, first: np.ndarray, second: np.ndarray) -> bytes:
    """Two members of the same name: which one a reader takes is up to the reader."""
    buf = io.BytesIO()
    with warnings.catch_warnings(), zipfile.ZipFile(buf, "w") as zf:
        warnings.simplefilter("ignore")  # zipfile warns about the duplicate name
        for array in (first, second):
            with zf.open(f"{key}.npy", "w") as f:
                np.lib.format.write_array(f, array)
    return buf.getvalue()


def huge_header_npz(key: str) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        header = b"{'descr': '<f4', 'fortran_order': False, 'shape': (3,), " + b" " * 200_000 + b"}\n"
        zf.writestr(f"{key}.npy", b"\x93NUMPY\x02\x00" + len(header).to_bytes(4, "little") + header)
    return buf.getvalue()


def small_pair() -> dict[str, np.ndarray]:
    rng = np.random.default_rng(0)
    mask = np.zeros((24, 32), bool)
    mask[8:16, 10:20] = True
    depth1 = np.full((24, 32), 0.5, np.float32)
    depth1[mask] = 0.6
    return {
        "rgb0": rng.integers(0, 255, (24, 32, 3), dtype=np.uint8),
        "depth0": np.full((24, 32), 1.0, np.float32),
        "mask0": mask,
        "rgb1": rng.integers(0, 255, (24, 32, 3), dtype=np.uint8),
        "depth1": depth1,
        "depth1_kind": np.array("disparity"),
        "mask1": np.roll(mask, 2, axis=1),
        "K": np.array([[30.0, 0, 15.5], [0, 30.0, 11.5], [0, 0, 1]]),
    }


odd_dtypes = st.sampled_from(["uint8", "int64", "float16", "float32", "float64", "bool", "complex64", "<U7", ">f8"])
odd_values = st.one_of(extreme_floats, st.sampled_from([0.0, -1.0, 1e38, 1e308, 65535.0]))


@st.composite
def mutated_arrays(draw, arrays: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The arrays with one key dropped, added, recast, reshaped or filled with absurd values."""
    arrays = dict(arrays)
    key = draw(st.sampled_from(sorted(arrays)))
    mutation = draw(st.sampled_from(["dtype", "shape", "value", "fill", "drop", "extra", "object", "none"]))
    a = arrays[key]
    if mutation == "dtype":
        try:
            arrays[key] = a.astype(draw(odd_dtypes))
        except (TypeError, ValueError):
            arrays[key] = np.zeros(a.shape, draw(odd_dtypes))
    elif mutation == "shape":
        shape = tuple(draw(st.lists(st.integers(0, 40), max_size=4)))
        arrays[key] = np.zeros(shape, a.dtype)
    elif mutation == "value" and a.size and a.dtype.kind == "f":
        b = a.copy()
        with np.errstate(over="ignore"):  # 1e308 in a float32 array is inf: one more bad value
            b.flat[draw(st.integers(0, a.size - 1))] = draw(odd_values)
        arrays[key] = b
    elif mutation == "fill" and a.dtype.kind == "f":
        with np.errstate(over="ignore"):
            arrays[key] = np.full(a.shape, draw(odd_values), a.dtype)
    elif mutation == "drop":
        del arrays[key]
    elif mutation == "extra":
        arrays[draw(st.text("abcdefgh_0", min_size=1, max_size=8))] = np.zeros(3)
    elif mutation == "object":
        arrays[key] = np.array([{"x": 1}, None], dtype=object)
    return arrays


@st.composite
def npz_files(draw, valid: dict[str, np.ndarray]) -> bytes:
    """An .npz built from valid arrays, mutated, maybe compressed, maybe broken at the byte level, or crafted."""
    family = draw(
        st.sampled_from(["mutated", "mutated", "mutated", "bytes", "bomb", "members", "header", "npy", "encrypted"])
    )
    key = draw(st.sampled_from(sorted(valid)))
    if family == "bomb":
        side = draw(st.sampled_from([65536, 100_000, 2**31]))
        descr = draw(st.sampled_from(["<f4", "|u1", "|b1", "<f8", "<U1000000000"]))
        return declared_npz({key: (descr, (side, side) if descr[1] != "U" else ())})
    if family == "members":
        return many_members_npz(draw(st.sampled_from([33, 2000])))
    if family == "header":
        return huge_header_npz(key)
    if family == "encrypted":
        return encrypted_npz(valid)
    if family == "npy":
        buf = io.BytesIO()
        np.save(buf, valid[key])
        return buf.getvalue()
    data = npz_bytes(draw(mutated_arrays(valid)), compressed=draw(st.booleans()))
    return draw(corrupted(data)) if family == "bytes" else data


# -- YAML profiles ------------------------------------------------------------------------------------------
ALIAS_BOMB = "\n".join(
    [f"a0: &a0 [{', '.join(['x'] * 9)}]"]
    + [f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 9)}]" for i in range(1, 9)]
    + ["safety: {padding_m: 0.01}"]
)


def yaml_number(x: float) -> str:
    if math.isnan(x):
        return ".nan"
    if math.isinf(x):
        return ".inf" if x > 0 else "-.inf"
    return repr(x)
