"""Reading files that a person or another tool wrote: profiles, scenes, boards, calibrations, TRAJ.json,
WORLD.json, PAIR.npz and point clouds.

Every reader is bounded before it builds anything: the file must be a regular file under a size limit and UTF-8
where it is text; JSON may not nest deeper or hold more values than a limit, nor integers longer than any real
number needs; YAML may not repeat a key in a mapping, nest or expand (aliases) without bound; an .npz archive
may hold only a few members, and every member's declared shape and dtype (its .npy header) is checked against a
byte budget before a single array is read, so a small compressed file cannot unpack into gigabytes. Whatever is
wrong raises InputFileError, which names the file, the key (or line) and the problem.
"""

from __future__ import annotations

import json
import math
import re
import stat
import struct
import zipfile
import zlib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import yaml

MAX_TEXT_BYTES = 32 * 2**20  # [B] far above any profile, scene, trajectory or world file
MAX_JSON_DEPTH = 32
MAX_JSON_VALUES = 2_000_000  # numbers, strings, lists, objects: the memory a parsed file may take (~100 MB)
MAX_NUMBER_CHARS = 40  # an integer or float written with more characters is not a measurement
MAX_YAML_BYTES = 4 * 2**20
MAX_YAML_NODES = 100_000  # counted with every alias expanded
MAX_YAML_DEPTH = 32
MAX_NPZ_MEMBERS = 32
MAX_NPZ_DIRECTORY_BYTES = 2**20
MAX_NPY_HEADER_BYTES = 10_000


class InputFileError(ValueError):
    """A file cannot be used. `file`, `key` (dotted path), `line` and `column` (1-based) and `problem` say where
    and what (key, line and column may be None); str() reads `FILE[:LINE[:COLUMN]]: [KEY: ]PROBLEM`."""

    def __init__(
        self,
        file: str | Path,
        problem: str,
        key: str | None = None,
        line: int | None = None,
        column: int | None = None,
    ) -> None:
        self.file, self.problem, self.key, self.line, self.column = Path(file), problem, key, line, column
        where = str(file)
        if line is not None:
            where += f":{line}" + (f":{column}" if column is not None else "")
        super().__init__(f"{where}: {key}: {problem}" if key else f"{where}: {problem}")


# -- raw bytes and text ---------------------------------------------------------------------------------------
def _regular_file(path: Path, what: str, max_bytes: int) -> int:
    """Size of path, refused when it is not a regular file (a FIFO or device would block or never end) or
    larger than max_bytes."""
    try:
        info = path.stat()
    except OSError as e:
        raise InputFileError(path, f"cannot read {what} ({e.strerror or e})") from None
    if not stat.S_ISREG(info.st_mode):
        kind = "a directory" if stat.S_ISDIR(info.st_mode) else "not a regular file"
        raise InputFileError(path, f"cannot read {what}: {kind}")
    if info.st_size > max_bytes:
        raise InputFileError(path, f"cannot read {what}: {info.st_size:,} bytes, more than the {max_bytes:,} allowed")
    return info.st_size


def read_bytes(path: Path, what: str, max_bytes: int) -> bytes:
    """The whole file, within max_bytes."""
    path = Path(path)
    _regular_file(path, what, max_bytes)
    try:
        with path.open("rb") as f:
            data = f.read(max_bytes + 1)  # the file may have grown since
    except OSError as e:
        raise InputFileError(path, f"cannot read {what} ({e.strerror or e})") from None
    if len(data) > max_bytes:
        raise InputFileError(path, f"cannot read {what}: more than the {max_bytes:,} bytes allowed")
    return data


def decode_utf8(data: bytes, path: Path, what: str) -> str:
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as e:
        line = data.count(b"\n", 0, e.start) + 1
        raise InputFileError(
            path, f"cannot read {what}: not UTF-8 text (byte 0x{data[e.start]:02x} at offset {e.start})", line=line
        ) from None


def read_text(path: Path, what: str, max_bytes: int = MAX_TEXT_BYTES) -> str:
    return decode_utf8(read_bytes(path, what, max_bytes), Path(path), what)


# -- JSON -----------------------------------------------------------------------------------------------------
_JSON_STRING = re.compile(rb'"[^"\\]*(?:\\.[^"\\]*)*"')  # unrolled: linear even on an unterminated string
_SCAN_CHUNK = 2**20


class _LongNumber(ValueError):
    def __init__(self, text: str) -> None:
        super().__init__(text)
        self.text = text


def _json_structure(data: bytes) -> tuple[int, int]:
    """(deepest nesting, an upper bound on the number of values) of JSON text, strings excluded, in bounded
    memory: counted chunk by chunk."""
    bare = np.frombuffer(_JSON_STRING.sub(b'""', data), np.uint8)
    depth = deepest = 0
    values = 1
    for start in range(0, len(bare), _SCAN_CHUNK):
        c = bare[start : start + _SCAN_CHUNK]
        opens = (c == ord("[")) | (c == ord("{"))
        delta = opens.astype(np.int64) - ((c == ord("]")) | (c == ord("}")))
        running = depth + np.cumsum(delta)
        deepest = max(deepest, int(running.max()))
        depth = int(running[-1])
        values += int(np.count_nonzero(c == ord(","))) + int(np.count_nonzero(opens))
    return deepest, values


def _json_int(text: str) -> int:
    if len(text) > MAX_NUMBER_CHARS:
        raise _LongNumber(text)
    return int(text)


def _json_float(text: str) -> float:
    if len(text) > MAX_NUMBER_CHARS:
        raise _LongNumber(text)
    return float(text)


class _DuplicateKey(ValueError):
    def __init__(self, key: str) -> None:
        super().__init__(key)
        self.key = key


def _json_object(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise _DuplicateKey(key)
        out[key] = value
    return out


def load_json(path: Path, what: str, max_bytes: int = MAX_TEXT_BYTES, max_values: int = MAX_JSON_VALUES) -> Any:
    """Parse a JSON file within the bounds above; a key repeated in one object is an error. NaN/Infinity
    literals and out-of-range floats (1e999 -> inf) are returned as floats for the schema to refuse by key."""
    path = Path(path)
    data = read_bytes(path, what, max_bytes)
    text = decode_utf8(data, path, what)
    deepest, values = _json_structure(data)
    if deepest > MAX_JSON_DEPTH:
        raise InputFileError(path, f"cannot read {what}: nested {deepest} levels deep (at most {MAX_JSON_DEPTH})")
    if values > max_values:
        raise InputFileError(path, f"cannot read {what}: about {values:,} values (at most {max_values:,})")
    try:
        return json.loads(text, parse_int=_json_int, parse_float=_json_float, object_pairs_hook=_json_object)
    except json.JSONDecodeError as e:
        problem = "empty file" if not text.strip() else f"invalid JSON ({e.msg})"
        raise InputFileError(path, f"cannot read {what}: {problem}", line=e.lineno, column=e.colno) from None
    except _DuplicateKey as e:
        raise InputFileError(
            path, f"cannot read {what}: key repeated in one object (JSON keeps only the last)", e.key
        ) from None
    except _LongNumber as e:
        at = text.find(e.text)
        line = text.count("\n", 0, at) + 1 if at >= 0 else None
        problem = f"cannot read {what}: a number written with {len(e.text):,} characters (at most {MAX_NUMBER_CHARS})"
        raise InputFileError(path, problem, line=line) from None
    except RecursionError:  # unreachable after the depth check; kept so no input can end in a traceback
        raise InputFileError(path, f"cannot read {what}: nested too deeply") from None


# -- YAML -----------------------------------------------------------------------------------------------------
class _BoundedLoader(yaml.SafeLoader):
    """SafeLoader whose numbers are bounded in length (no 5000-digit integer, no sexagesimal giant)."""


def _bounded_number(constructor):
    def construct(loader: _BoundedLoader, node: yaml.ScalarNode):
        if len(node.value) > MAX_NUMBER_CHARS:
            raise yaml.constructor.ConstructorError(
                None, None, f"a number written with {len(node.value):,} characters", node.start_mark
            )
        return constructor(loader, node)

    return construct


_BoundedLoader.add_constructor("tag:yaml.org,2002:int", _bounded_number(yaml.SafeLoader.construct_yaml_int))
_BoundedLoader.add_constructor("tag:yaml.org,2002:float", _bounded_number(yaml.SafeLoader.construct_yaml_float))
_MERGE_TAG = "tag:yaml.org,2002:merge"


def _check_yaml_tree(root: yaml.Node, path: Path, what: str, max_nodes: int) -> None:
    """Duplicate keys, depth and size (aliases expanded) of a composed document, walked without recursion."""
    stack: list[tuple[yaml.Node, tuple[str, ...]]] = [(root, ())]
    visited = 0
    while stack:
        node, key_path = stack.pop()
        visited += 1
        line = node.start_mark.line + 1
        if visited > max_nodes:
            raise InputFileError(path, f"cannot read {what}: more than {max_nodes:,} values (aliases expanded)")
        if len(key_path) > MAX_YAML_DEPTH:
            key = ".".join(key_path[:4]) + ". ..."
            raise InputFileError(path, f"nested more than {MAX_YAML_DEPTH} levels deep", key, line)
        if isinstance(node, yaml.MappingNode):
            first: dict[tuple[str, str], int] = {}
            for key_node, value in node.value:
                name = str(key_node.value) if isinstance(key_node, yaml.ScalarNode) else "<complex key>"
                if isinstance(key_node, yaml.ScalarNode) and key_node.tag != _MERGE_TAG:
                    ident = (key_node.tag, key_node.value)
                    key_line = key_node.start_mark.line + 1
                    if ident in first:
                        dotted = ".".join((*key_path, name))
                        raise InputFileError(
                            path,
                            f"duplicate key (first set at line {first[ident]})",
                            dotted,
                            key_line,
                            key_node.start_mark.column + 1,
                        )
                    first[ident] = key_line
                stack.append((value, (*key_path, name)))
        elif isinstance(node, yaml.SequenceNode):
            stack.extend((item, (*key_path, str(i))) for i, item in enumerate(node.value))


def load_yaml(path: Path, what: str, max_bytes: int = MAX_YAML_BYTES, max_nodes: int = MAX_YAML_NODES) -> Any:
    """Parse one YAML document safely; a repeated key anywhere is an error naming it and both lines."""
    path = Path(path)
    text = read_text(path, what, max_bytes)
    loader = None
    try:
        loader = _BoundedLoader(text)  # its reader refuses control characters here
        node = loader.get_single_node()
        if node is None:
            return None
        _check_yaml_tree(node, path, what, max_nodes)
        return loader.construct_document(node)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        line, column = (mark.line + 1, mark.column + 1) if mark is not None else (None, None)
        problem = getattr(e, "problem", None) or str(e)
        raise InputFileError(path, f"invalid YAML ({problem})", line=line, column=column) from None
    except RecursionError:
        raise InputFileError(path, f"cannot read {what}: nested too deeply") from None
    finally:
        if loader is not None:
            loader.dispose()


# -- NPZ ------------------------------------------------------------------------------------------------------
_EOCD = b"PK\x05\x06"
_EOCD_SEARCH = 2**16 + 22  # the end record sits within the last 64 KiB (its comment) + 22 bytes
_READ_ERRORS = (  # what zipfile and numpy raise on a broken archive; RuntimeError: an encrypted member
    OSError,
    EOFError,
    ValueError,
    RuntimeError,
    zipfile.BadZipFile,
    zlib.error,
    NotImplementedError,
    struct.error,
)
HeaderCheck = Callable[[str, tuple[int, ...], np.dtype], None]


def _check_zip_directory(path: Path, what: str, max_file_bytes: int) -> None:
    """A regular file under the size limit whose zip end record lists few members in a small directory, checked
    before zipfile parses (and allocates for) that directory."""
    size = _regular_file(path, what, max_file_bytes)
    try:
        with path.open("rb") as f:
            head = f.read(6)
            f.seek(max(0, size - _EOCD_SEARCH))
            tail = f.read(_EOCD_SEARCH)
    except OSError as e:
        raise InputFileError(path, f"cannot read {what} ({e.strerror or e})") from None
    if head == b"\x93NUMPY":
        raise InputFileError(path, f"cannot read {what}: a single .npy array, not an .npz archive of named arrays")
    at = tail.rfind(_EOCD)
    if at < 0 or len(tail) - at < 22:
        problem = "empty file" if size == 0 else "not an .npz archive (no zip directory: truncated?)"
        raise InputFileError(path, f"cannot read {what}: {problem}")
    entries, directory = struct.unpack("<HI", tail[at + 10 : at + 16])
    if entries > MAX_NPZ_MEMBERS or directory > MAX_NPZ_DIRECTORY_BYTES:
        raise InputFileError(
            path, f"cannot read {what}: {entries:,} members in {directory:,} bytes (at most {MAX_NPZ_MEMBERS} members)"
        )


def _npy_header(f, path: Path, key: str) -> tuple[tuple[int, ...], np.dtype]:
    version = np.lib.format.read_magic(f)
    if version == (1, 0):
        shape, _, dtype = np.lib.format.read_array_header_1_0(f, max_header_size=MAX_NPY_HEADER_BYTES)
    elif version in ((2, 0), (3, 0)):
        shape, _, dtype = np.lib.format.read_array_header_2_0(f, max_header_size=MAX_NPY_HEADER_BYTES)
    else:
        raise InputFileError(path, f"unsupported .npy format version {version}", key)
    return tuple(int(n) for n in shape), dtype


def read_npz(
    path: Path, what: str, max_file_bytes: int, max_array_bytes: int, check: HeaderCheck | None = None
) -> dict[str, np.ndarray]:
    """Every array of an .npz archive (np.savez / savez_compressed), without pickles. All member headers are
    read first; an object dtype, a declared size above max_array_bytes (one array, or all of them together) or
    a ValueError from `check(key, shape, dtype)` refuses the file before any array is loaded, so a compressed
    archive cannot unpack into more than that."""
    path = Path(path)
    _check_zip_directory(path, what, max_file_bytes)
    arrays: dict[str, np.ndarray] = {}
    key = None
    try:
        with zipfile.ZipFile(path) as zf:
            members = [info for info in zf.infolist() if not info.is_dir()]
            declared = 0
            names = [info.filename for info in members]
            for info in members:
                key = info.filename.removesuffix(".npy")
                if not info.filename.endswith(".npy"):
                    raise InputFileError(path, "not an .npy member", info.filename)
                if names.count(info.filename) > 1:
                    raise InputFileError(path, "member repeated in the archive (which one counts?)", key)
                with zf.open(info) as f:
                    shape, dtype = _npy_header(f, path, key)
                if dtype.hasobject:
                    raise InputFileError(path, f"dtype {dtype} holds Python objects (not loaded)", key)
                nbytes = math.prod(shape) * dtype.itemsize
                declared += nbytes
                if declared > max_array_bytes:
                    raise InputFileError(
                        path,
                        f"declares {dtype} {shape} ({nbytes:,} bytes): the arrays would take more than the "
                        f"{max_array_bytes:,} bytes allowed",
                        key,
                    )
                if check is not None:
                    try:
                        check(key, shape, dtype)
                    except ValueError as e:  # what the caller's layout forbids
                        raise InputFileError(path, str(e), key) from None
            for info in members:
                key = info.filename.removesuffix(".npy")
                with zf.open(info) as f:
                    arrays[key] = np.lib.format.read_array(f, allow_pickle=False, max_header_size=MAX_NPY_HEADER_BYTES)
    except InputFileError:
        raise
    except _READ_ERRORS as e:
        where = f"{key}: " if key else ""
        raise InputFileError(path, f"cannot read {what} as .npz ({where}{e})") from None
    return arrays


# -- output paths ---------------------------------------------------------------------------------------------
def check_output_path(path: Path, what: str, folder: bool = False) -> None:
    """Refuse, before any work, an output path that cannot be what it should be: a file path that is a directory,
    a folder path that is a file, or either below an existing file."""
    path = Path(path)
    if path.exists() and path.is_dir() != folder:
        raise InputFileError(path, f"cannot write {what}: {'not a folder' if folder else 'a directory'}")
    for parent in path.parents:
        if parent.exists():
            if not parent.is_dir():
                raise InputFileError(path, f"cannot write {what}: {parent} is not a directory")
            break
