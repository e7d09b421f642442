"""The fuzz harness behind tests/fuzz and benchmarks/bench_fuzz.py.

Every case is an argument list for ``lander`` (``autonomy.cli.main``), run in a worker
process forked from this one (the heavy imports are done once, before the fork) with stdout
and stderr captured as the terminal would encode them (UTF-8; strict on stdout,
backslashreplace on stderr). A case passes when it ends with an allowed exit code (0, 1 or
2), raised nothing (the worker sets LANDER_TRACEBACK=1, so a bug raises instead of becoming
the CLI's "internal error" line), printed no traceback (threads included) and no library
warning, and every line it printed to stderr on exit 2 is a ``lander CMD: error: ...`` line
with a field or flag name. A case that does not answer within its deadline is a hang: the
worker is killed and a new one forked.

The inputs (hypothesis strategies):

- mission documents generated from the schema (``Mission.model_json_schema()``): every
  section, with values inside, at and beyond each bound;
- mutations of the valid missions in missions/: keys deleted, duplicated, retyped, set to
  extremes (1e308, 2**64, -0.0, ...), NaN/inf, unicode (RTL, combining, NUL, lone
  surrogates), unknown keys, deep nesting, huge lists, YAML alias bombs, raw text damage
  (truncation, invalid UTF-8, tabs);
- argument lists for every subcommand, built from its argparse definition: each option with
  good, extreme and junk values, unknown options, and the files below;
- corrupt input files for ``lander detect`` (.npy, PLY, LAS/LAZ with laspy, 16-bit PNG) and
  for ``world: file`` (.npy, ESRI .asc, GeoTIFF), written into the work directory.

What the generators avoid on purpose, because it is valid and long by design: flights are
capped at ``FLY_TIME_LIMIT`` simulated seconds (a mutated mission keeps at most that
``time_limit``), ``lander sitl`` always gets a short ``--duration`` and an ephemeral port
(never the well-known 5760/14550), live URLs point at a closed local port, campaigns fly at
most two runs on one worker.
"""

from __future__ import annotations

import copy
import io
import math
import multiprocessing
import os
import re
import signal
import socket
import sys
import tempfile
import time
import traceback
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from hypothesis import strategies as st

ROOT = Path(__file__).resolve().parents[2]
MISSIONS = ROOT / "missions"
FLY_TIME_LIMIT = 120.0
ALLOWED_EXIT = frozenset({0, 1, 2})
ERROR_LINE = re.compile(r"^lander(?: [a-z]+)?: (?:error|internal error): \S")
EMPTY_FIELD = re.compile(r"(?:error: :|: : |override :|override  )")
WARNING_LINE = re.compile(r"\b\w*Warning: ")
TRACEBACK_TEXT = "Traceback (most recent call last)"
MAX_OUTPUT = 20_000


# --------------------------------------------------------------------------------------
# Running cases


@dataclass
class Result:
    """What one case did."""

    argv: list[str]
    code: int | None = None
    out: str = ""
    err: str = ""
    traceback: str | None = None
    seconds: float = 0.0
    hang: bool = False
    died: str | None = None
    allowed: frozenset[int] = ALLOWED_EXIT

    def problems(self) -> list[str]:
        """Why the case fails the promise (empty: it held)."""
        found = []
        if self.hang:
            found.append(f"hang: no answer within {self.seconds:.0f} s")
            return found
        if self.died:
            found.append(f"worker died: {self.died}")
            return found
        if self.traceback:
            found.append("traceback: " + self.traceback.strip().splitlines()[-1])
        if TRACEBACK_TEXT in self.err or TRACEBACK_TEXT in self.out:
            found.append("a traceback was printed")
        if self.code not in self.allowed:
            found.append(f"exit code {self.code}")
        lines = [line for line in self.err.splitlines() if line.strip() and line != CUT]
        for line in lines:
            if WARNING_LINE.search(line):
                found.append(f"library warning on stderr: {line[:200]}")
                break
        if self.code == 2:
            if not lines:
                found.append("exit 2 without a line saying why")
            for line in lines:
                if not ERROR_LINE.match(line):
                    found.append(f"not one clear line in the project's words: {line[:200]}")
                    break
                if EMPTY_FIELD.search(line):
                    found.append(f"an empty field name: {line[:200]}")
                    break
        return found

    def kind(self) -> str | None:
        """'hang', 'traceback' or 'other' for a failed case, None for one that held."""
        problems = self.problems()
        if not problems:
            return None
        if self.hang:
            return "hang"
        if self.traceback or any("traceback" in p for p in problems) or self.died:
            return "traceback"
        return "other"

    def describe(self) -> str:
        text = f"lander {' '.join(self.argv)}\n  " + "\n  ".join(self.problems())
        if self.traceback:
            text += "\n" + self.traceback
        elif self.err:
            text += "\n  stderr: " + self.err[-1500:]
        return text


def _preload() -> None:
    """Import what the commands import, once, before forking workers."""
    import autonomy.cli
    import autonomy.runner  # noqa: F401
    import lsd.depth_costmap.detector  # noqa: F401
    import lsd.elevation.detector  # noqa: F401
    import lsd.io  # noqa: F401
    import lsd.lidar_pca.detector  # noqa: F401
    import sitl.terrain  # noqa: F401

    autonomy.cli.build_parser()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot  # noqa: F401


def _serve(conn: Any, workdir: str) -> None:
    """The worker: run argument lists from ``conn`` until it sends None."""
    os.chdir(workdir)
    os.environ["LANDER_TRACEBACK"] = "1"
    os.environ.pop("LANDER_SIGNING_KEY", None)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    try:  # a bound on memory, so a case that would take the machine's is an error instead
        import resource

        limit = 6 * 1024**3
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    except (ImportError, ValueError, OSError):
        pass
    from autonomy.cli import main

    real_out, real_err = sys.stdout, sys.stderr
    while True:
        argv = conn.recv()
        if argv is None:
            return
        out_buf, err_buf = io.BytesIO(), io.BytesIO()
        out = io.TextIOWrapper(out_buf, encoding="utf-8", errors="strict", write_through=True)
        err = io.TextIOWrapper(err_buf, encoding="utf-8", errors="backslashreplace",
                               write_through=True)
        sys.stdout, sys.stderr = out, err
        # What C libraries (OpenCV, GDAL, ...) and child processes write to the file
        # descriptors is what a user would see too.
        fd_file = tempfile.TemporaryFile()
        saved = os.dup(1), os.dup(2)
        os.dup2(fd_file.fileno(), 1)
        os.dup2(fd_file.fileno(), 2)
        code: int | None = None
        tb = None
        start = time.perf_counter()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("default")  # shown, as a user would see them
                warnings.showwarning = _show_warning(err)
                code = main(list(argv))
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
        except BaseException:  # noqa: BLE001 - anything escaping main is what we look for
            tb = traceback.format_exc()
        finally:
            sys.stdout, sys.stderr = real_out, real_err
            try:
                out.flush()
                err.flush()
            except Exception:  # noqa: BLE001
                pass
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            os.close(saved[0])
            os.close(saved[1])
        seconds = time.perf_counter() - start
        fd_file.seek(0)
        raw = fd_file.read(MAX_OUTPUT)
        fd_file.close()
        err_text = _text(err_buf) + raw.decode("utf-8", errors="replace")
        conn.send((code, _text(out_buf), err_text, tb, seconds))


def _show_warning(stream: Any) -> Any:
    def show(message, category, filename, lineno, file=None, line=None):
        stream.write(warnings.formatwarning(message, category, filename, lineno, line))

    return show


CUT = "[output cut by the fuzz harness]"


def _text(buf: io.BytesIO) -> str:
    """The output, its middle cut (at line ends) when it is long."""
    data = buf.getvalue()
    if len(data) > MAX_OUTPUT:
        head = data[:2000].rsplit(b"\n", 1)[0]
        tail = data[-(MAX_OUTPUT - 2000):].split(b"\n", 1)[-1]
        data = head + b"\n" + CUT.encode() + b"\n" + tail
    return data.decode("utf-8", errors="replace")


class Runner:
    """Runs cases in a forked worker with a deadline each; a hung worker is killed."""

    def __init__(self, workdir: Path, deadline: float = 120.0) -> None:
        self.workdir = Path(workdir)
        self.workdir.mkdir(parents=True, exist_ok=True)
        self.deadline = deadline
        self._context = multiprocessing.get_context("fork")
        self._process: Any = None
        self._conn: Any = None
        _preload()

    def _start(self) -> None:
        parent, child = self._context.Pipe()
        # Not a daemon: campaigns start process pools, which daemons may not.
        self._process = self._context.Process(target=_serve, args=(child, str(self.workdir)))
        self._process.start()
        child.close()
        self._conn = parent

    def _stop(self, kill: bool = False) -> None:
        if self._process is None:
            return
        if kill:
            try:
                self._process.kill()  # our own worker, by its pid
            except OSError:
                pass
        else:
            try:
                self._conn.send(None)
            except OSError:
                pass
        self._process.join(timeout=10)
        if self._process.is_alive():
            self._process.kill()
            self._process.join(timeout=10)
        self._conn.close()
        self._process = self._conn = None

    def run(self, argv: list[str], deadline: float | None = None,
            allowed: frozenset[int] = ALLOWED_EXIT) -> Result:
        deadline = self.deadline if deadline is None else deadline
        if self._process is None or not self._process.is_alive():
            self._start()
        result = Result(argv=list(argv), allowed=allowed)
        start = time.perf_counter()
        try:
            self._conn.send(list(argv))
            if not self._conn.poll(deadline):
                result.hang = True
                result.seconds = time.perf_counter() - start
                self._stop(kill=True)
                return result
            code, out, err, tb, seconds = self._conn.recv()
        except (EOFError, OSError, BrokenPipeError) as exc:
            code = self._process.exitcode if self._process is not None else None
            result.died = f"{type(exc).__name__} (exit code {code})"
            result.seconds = time.perf_counter() - start
            self._stop(kill=True)
            return result
        result.code, result.out, result.err, result.traceback = code, out, err, tb
        result.seconds = seconds
        return result

    def close(self) -> None:
        self._stop()

    def __del__(self) -> None:  # a worker must not outlive its runner
        if self._process is not None and self._process.is_alive():
            self._process.kill()


# --------------------------------------------------------------------------------------
# Values


EXTREME_NUMBERS = (
    0, -0.0, -1, 1, 0.5, 1e-320, 5e-324, 1e-9, 1e308, -1e308, 1.7976931348623157e308, 1e39,
    -1e39, 1e23, 2**31, 2**31 - 1, 2**32, 2**32 - 1, 2**63, -(2**63), 2**64, 10**30,
    -(10**30), 100_000, 1_000_000_000, 3.4e38, 65536, 65535, 255, 256, -255,
)
SPECIAL_FLOATS = (math.nan, math.inf, -math.inf)
UNICODE_TEXT = (
    "", " ", "\t", "é", "名前", "🚁", "\u202eRTL\u202c", "e\u0301", "\x00", "\x07bell",
    "a\nb", "\ud800", "\udfff", "\ufeff", "'", '"', "{", "[", "*alias", "&anchor", "!!python",
    "%", "- ", ": ", "#", "null", "~", "yes", "no", "on", "1e3", "0x10", "0o17", ".nan",
    "-.inf", "x" * 5000, "..", "/", "\\\\", "sim://", "../../etc/passwd", "C:\\x",
)
KEY_TEXT = UNICODE_TEXT[:20] + ("typo", "Waypoints", "waypoint", "__class__", "0", "1.5")


def numbers() -> st.SearchStrategy[Any]:
    return st.one_of(
        st.sampled_from(EXTREME_NUMBERS),
        st.sampled_from(SPECIAL_FLOATS),
        st.integers(min_value=-(2**70), max_value=2**70),
        st.floats(allow_nan=True, allow_infinity=True),
        st.floats(min_value=-1e6, max_value=1e6),
    )


def scalars() -> st.SearchStrategy[Any]:
    return st.one_of(
        numbers(), st.booleans(), st.none(), st.sampled_from(UNICODE_TEXT), st.text(max_size=20)
    )


def junk_values() -> st.SearchStrategy[Any]:
    leaf = scalars()
    return st.one_of(
        leaf,
        st.lists(leaf, max_size=4),
        st.dictionaries(st.sampled_from(KEY_TEXT), leaf, max_size=3),
        st.lists(st.lists(leaf, max_size=3), max_size=3),
    )


def cli_numbers() -> st.SearchStrategy[str]:
    return st.one_of(
        st.sampled_from(["0", "-0", "1", "-1", "0.5", "2", "10", "1e3", "1e308", "-1e308",
                         "1e-320", "nan", "inf", "-inf", "NaN", "4294967295", "4294967296",
                         "-5", "99999999999999999999999", "0x10", "1_000", "", " ", "abc",
                         "1,2", "٣", "1e", "--", "3.5"]),
        st.integers(min_value=-(2**66), max_value=2**66).map(str),
        st.floats(allow_nan=True, allow_infinity=True).map(repr),
    )


# --------------------------------------------------------------------------------------
# Mission documents


def _schema() -> dict[str, Any]:
    from autonomy.config import Mission

    return Mission.model_json_schema()


def _resolve(node: dict[str, Any], defs: dict[str, Any]) -> dict[str, Any]:
    while "$ref" in node:
        node = defs[node["$ref"].rsplit("/", 1)[-1]]
    return node


def _bounded_number(node: dict[str, Any], integer: bool, junk: bool = True
                    ) -> st.SearchStrategy[Any]:
    low = node.get("minimum", node.get("exclusiveMinimum"))
    high = node.get("maximum", node.get("exclusiveMaximum"))
    open_low, open_high = "exclusiveMinimum" in node, "exclusiveMaximum" in node
    lo = -1e6 if low is None else low
    hi = 1e6 if high is None else high
    if integer:
        lo_i, hi_i = math.ceil(lo + open_low), math.floor(hi - open_high)
        inside = st.integers(min_value=int(min(lo_i, hi_i)), max_value=int(max(lo_i, hi_i)))
        edges = [v for v in (low, high) if v is not None]
        edge = st.sampled_from([int(v) + d for v in edges for d in (-1, 0, 1)] or [0])
    else:
        inside = st.floats(min_value=lo, max_value=hi, exclude_min=open_low,
                           exclude_max=open_high, allow_nan=False)
        edges = [v for v in (low, high) if v is not None]
        edge = st.sampled_from(
            [v + d for v in edges for d in (-1e-9 * max(1, abs(v)), 0.0, 1e-9 * max(1, abs(v)))]
            or [0.0]
        )
    if not junk:
        return st.one_of(inside, inside, inside, edge)
    return st.one_of(inside, inside, inside, edge, numbers())


TYPICAL_TEXT = {
    "connection": ["sim://", "sim://px4", "sim://ardupilot?seed=2"],
    "signing_key": ["secret", "ab" * 32],
    "signing_key_env": ["PATH"],
    "source": ["elevation"],
}
"""Strings that fields expect, for documents generated without junk."""


def from_schema(node: dict[str, Any], defs: dict[str, Any], depth: int = 0,
                junk: bool = True, name: str = "") -> st.SearchStrategy[Any]:
    """Values for a JSON-schema node: of the right type and in range or at a bound, and
    with ``junk`` sometimes not."""
    node = _resolve(node, defs)
    if depth > 8:
        return scalars()
    if "const" in node:
        return st.just(node["const"])
    if "enum" in node:
        if not junk:
            return st.sampled_from(node["enum"])
        return st.one_of(st.sampled_from(node["enum"]), st.sampled_from(node["enum"]),
                         st.sampled_from(UNICODE_TEXT[:10]))
    for key in ("oneOf", "anyOf"):
        if key in node:
            options = [from_schema(option, defs, depth + 1, junk, name) for option in node[key]]
            return st.one_of(*options)
    kind = node.get("type")
    if kind == "object":
        properties = node.get("properties", {})
        required = set(node.get("required", ()))
        extra = node.get("additionalProperties")
        if isinstance(extra, dict):
            names = ["LOCAL_POSITION_NED", "ATTITUDE", "HEARTBEAT"]
            names += ["NOT_A_MESSAGE", ""] if junk else []
            return st.dictionaries(st.sampled_from(names),
                                   from_schema(extra, defs, depth + 1, junk), max_size=4)
        return st.fixed_dictionaries(
            {k: from_schema(v, defs, depth + 1, junk, k) for k, v in properties.items()
             if k in required},
            optional={k: from_schema(v, defs, depth + 1, junk, k)
                      for k, v in properties.items() if k not in required},
        )
    if kind == "array":
        if "prefixItems" in node:
            items = [from_schema(v, defs, depth + 1, junk) for v in node["prefixItems"]]
            exact = st.tuples(*items).map(list)
            if not junk:
                return exact
            return st.one_of(exact, exact, exact, st.lists(scalars(), max_size=4))
        item = from_schema(node.get("items", {}), defs, depth + 1, junk)
        low = node.get("minItems", 0)
        return st.lists(item, min_size=low, max_size=max(low, 1) + 3)
    if kind == "number":
        return _bounded_number(node, integer=False, junk=junk)
    if kind == "integer":
        return _bounded_number(node, integer=True, junk=junk)
    if kind == "boolean":
        return st.booleans() if not junk else st.one_of(st.booleans(), st.booleans(), scalars())
    if kind == "string":
        if node.get("format") == "path":
            good = ["world.npy", "world.asc"]
            return st.sampled_from(good if not junk else good + [
                "world.tif", "missing.npy", "bad.npy", "bad.asc", "bad.tif", "world.txt", "",
                "."])
        if not junk:
            return st.sampled_from(TYPICAL_TEXT.get(name, ["", "a mission"]))
        return st.one_of(st.text(max_size=30), st.sampled_from(UNICODE_TEXT))
    if kind == "null":
        return st.none()
    return scalars()


def schema_documents() -> st.SearchStrategy[dict[str, Any]]:
    """Mission documents generated from the schema: half with junk anywhere, half with every
    value of its type and within or at its bounds (which still breaks cross-field rules)."""
    schema = _schema()
    defs = schema.get("$defs", {})
    return st.one_of(from_schema(schema, defs, junk=True),
                     from_schema(schema, defs, junk=False)).filter(lambda d: isinstance(d, dict))


def base_missions() -> list[dict[str, Any]]:
    """The shipped missions as data, their flights capped at FLY_TIME_LIMIT."""
    docs = []
    for path in sorted(MISSIONS.glob("*.yaml")):
        doc = yaml.safe_load(path.read_text())
        doc["time_limit"] = min(float(doc.get("time_limit", 1800)), FLY_TIME_LIMIT)
        docs.append(doc)
    return docs


def _paths(value: Any, prefix: tuple = ()) -> list[tuple]:
    """Every location (tuple of keys/indexes) inside a document (down to 30 levels)."""
    out = [prefix]
    if len(prefix) > 30:
        return out
    if isinstance(value, dict):
        for key, child in value.items():
            out += _paths(child, (*prefix, key))
    elif isinstance(value, list):
        for i, child in enumerate(value[:50]):
            out += _paths(child, (*prefix, i))
    return out


def _schema_node(path: tuple) -> dict[str, Any] | None:
    """The JSON-schema node of the number at ``path`` in a mission document, or None."""
    schema = _SCHEMA.get("schema")
    if schema is None:
        schema = _SCHEMA["schema"] = _schema()
    defs = schema.get("$defs", {})
    node: Any = schema
    for key in path:
        node = _resolve(node, defs)
        for union in ("anyOf", "oneOf"):
            if union in node:
                options = [_resolve(o, defs) for o in node[union]]
                options = [o for o in options if o.get("type") != "null"]
                if isinstance(key, str):
                    options = [o for o in options if key in o.get("properties", {})]
                node = options[0] if options else {}
        if isinstance(key, str):
            node = node.get("properties", {}).get(key)
        elif "prefixItems" in node:
            items = node["prefixItems"]
            node = items[key] if key < len(items) else None
        else:
            node = node.get("items")
        if node is None:
            return None
    node = _resolve(node, defs)
    for union in ("anyOf", "oneOf"):
        if union in node:
            numbers = [o for o in node[union] if o.get("type") in ("number", "integer")]
            node = numbers[0] if numbers else node
    return node if node.get("type") in ("number", "integer") else None


_SCHEMA: dict[str, Any] = {}


def _schema_edges(path: tuple) -> list[Any]:
    """Valid extreme values of the number at ``path``: its bounds (just inside open ones)."""
    node = _schema_node(path)
    if node is None:
        return []
    integer = node.get("type") == "integer"
    edges: list[Any] = []
    for key, step in (("minimum", 0), ("maximum", 0), ("exclusiveMinimum", 1),
                      ("exclusiveMaximum", -1)):
        if key in node:
            value = node[key]
            if step:
                value = value + step if integer else (
                    math.nextafter(value, math.inf if step > 0 else -math.inf))
            edges.append(int(value) if integer else float(value))
    return edges


def _get(doc: Any, path: tuple) -> Any:
    for key in path:
        doc = doc[key]
    return doc


def _set(doc: Any, path: tuple, value: Any) -> None:
    _get(doc, path[:-1])[path[-1]] = value


def _delete(doc: Any, path: tuple) -> None:
    parent = _get(doc, path[:-1])
    del parent[path[-1]]


@st.composite
def mutated_documents(draw: Any, fly: bool = False) -> dict[str, Any]:
    """A shipped mission with 1-4 mutations (see the module docstring)."""
    bases = base_missions()
    doc = copy.deepcopy(draw(st.sampled_from(bases[:1] if fly else bases)))
    for _ in range(draw(st.integers(min_value=1, max_value=3 if fly else 4))):
        paths = [p for p in _paths(doc) if p]
        if not paths:
            break
        path = draw(st.sampled_from(paths))
        kinds = ["delete", "retype", "extreme", "extreme", "special", "unicode", "unknown",
                 "nest", "biglist", "swap", "bound", "bound", "world_file", "edge", "edge",
                 "edge", "edge"]
        if fly:  # mostly valid extremes, so that most of these missions fly
            kinds += ["edge"] * 30
        kind = draw(st.sampled_from(kinds))
        if kind == "edge":  # a number set to one of its schema bounds: valid, and extreme
            edges = _schema_edges(path)
            if edges:
                _set(doc, path, draw(st.sampled_from(edges)))
            continue
        target = _get(doc, path)
        try:
            if kind == "delete":
                _delete(doc, path)
            elif kind == "retype":
                _set(doc, path, draw(junk_values()))
            elif kind == "extreme":
                _set(doc, path, draw(st.sampled_from(EXTREME_NUMBERS)))
            elif kind == "special":
                _set(doc, path, draw(st.sampled_from(SPECIAL_FLOATS)))
            elif kind == "unicode":
                if isinstance(path[-1], str) and draw(st.booleans()):
                    parent = _get(doc, path[:-1])
                    parent[draw(st.sampled_from(KEY_TEXT))] = parent.pop(path[-1])
                else:
                    _set(doc, path, draw(st.sampled_from(UNICODE_TEXT)))
            elif kind == "unknown":
                parent = _get(doc, path[:-1])
                if isinstance(parent, dict):
                    parent[draw(st.sampled_from(KEY_TEXT))] = draw(scalars())
            elif kind == "nest":
                value: Any = target
                for _ in range(draw(st.sampled_from([3, 50, 200]))):
                    value = [value]
                _set(doc, path, value)
            elif kind == "biglist":
                n = draw(st.sampled_from([0, 1001, 5000, 100_000]))
                _set(doc, path, [target] * n)
            elif kind == "swap":
                if isinstance(target, list):
                    _set(doc, path, {str(i): v for i, v in enumerate(target)})
                elif isinstance(target, dict):
                    _set(doc, path, list(target.values()))
            elif kind == "bound":
                if isinstance(target, (int, float)) and not isinstance(target, bool):
                    factor = draw(st.sampled_from([0, -1, 0.001, 10, 1000, 1e6]))
                    _set(doc, path, type(target)(target * factor) if factor else target * 0)
            elif kind == "world_file":
                doc["world"] = {
                    "kind": "file",
                    "path": draw(st.sampled_from(["world.npy", "world.asc", "bad.npy", "bad.asc",
                                                  "bad.tif", "world.tif", "missing.npy"])),
                    **({"source_cell_size": draw(st.sampled_from([0.5, 1.0, 1e-6, 1e6]))}
                       if draw(st.booleans()) else {}),
                }
        except (KeyError, IndexError, TypeError):
            pass
    if fly and isinstance(doc, dict):
        limit = doc.get("time_limit")
        if isinstance(limit, (int, float)) and not isinstance(limit, bool) and (
            not limit <= FLY_TIME_LIMIT
        ) and math.isfinite(limit) and limit <= 14_400:
            doc["time_limit"] = FLY_TIME_LIMIT  # valid and long by design: keep it short
        vehicle = doc.get("vehicle")
        if isinstance(vehicle, dict):
            vehicle.setdefault("link", {})
            if isinstance(vehicle["link"], dict):
                vehicle["link"]["connect_timeout"] = 2.0
    return doc


def _dump(doc: Any) -> str:
    try:
        return yaml.safe_dump(doc, allow_unicode=True, sort_keys=False, width=10_000)
    except (yaml.YAMLError, RecursionError, ValueError):
        return yaml.safe_dump({"waypoints": [[0, 0, 10]], "note": repr(doc)[:1000]})


@st.composite
def mission_texts(draw: Any, documents: st.SearchStrategy[Any]) -> bytes:
    """YAML text of a document, sometimes damaged as text."""
    text = _dump(draw(documents))
    damage = draw(st.sampled_from(["none"] * 6 + ["truncate", "duplicate", "tab", "bytes",
                                                   "bomb", "bom", "empty", "scalar", "deep"]))
    data = text.encode("utf-8", errors="surrogateescape")
    lines = text.splitlines(keepends=True)
    if damage == "truncate" and data:
        data = data[: draw(st.integers(min_value=0, max_value=len(data) - 1))]
    elif damage == "duplicate" and lines:
        i = draw(st.integers(min_value=0, max_value=len(lines) - 1))
        data = "".join(lines[: i + 1] + [lines[i]] + lines[i + 1:]).encode(
            "utf-8", errors="surrogateescape")
    elif damage == "tab":
        data = data.replace(b"  ", b"\t", 1)
    elif damage == "bytes" and data:
        i = draw(st.integers(min_value=0, max_value=len(data) - 1))
        data = data[:i] + draw(st.sampled_from([b"\xff", b"\xc3", b"\x00", b"\xed\xa0\x80"])) \
            + data[i:]
    elif damage == "bomb":
        levels = "\n".join(
            f"l{i}: &l{i} [" + ", ".join([f"*l{i - 1}"] * 9) + "]" for i in range(1, 12)
        )
        data = (f"l0: &l0 [lol]\n{levels}\nwaypoints: *l11\nsites: *l11\n").encode()
    elif damage == "deep":
        depth = draw(st.sampled_from([100, 5000, 100_000]))
        data = b"waypoints: " + b"[" * depth + b"]" * depth + b"\n"
    elif damage == "bom":
        data = b"\xef\xbb\xbf" + data
    elif damage == "empty":
        data = draw(st.sampled_from([b"", b"\n", b"---\n", b"# nothing\n", b"...\n"]))
    elif damage == "scalar":
        data = draw(st.sampled_from([b"42\n", b"[1, 2]\n", b"null\n", b"- a\n- b\n",
                                     b"!!python/object:os.system x\n", b"--- a\n--- b\n"]))
    return data


# --------------------------------------------------------------------------------------
# Files


class Files:
    """The input files cases name, written once into the work directory (corrupt ones are
    drawn per case by :func:`corrupt_files`)."""

    def __init__(self, workdir: Path) -> None:
        self.dir = Path(workdir)
        self.dir.mkdir(parents=True, exist_ok=True)
        d = self.dir
        np.save(d / "world.npy", np.zeros((101, 101), dtype=np.float32))
        np.save(d / "bad.npy", np.zeros((3,)))
        (d / "world.asc").write_text(
            "ncols 11\nnrows 11\nxllcorner 0\nyllcorner 0\ncellsize 10\nNODATA_value -9999\n"
            + "\n".join(" ".join("0" for _ in range(11)) for _ in range(11)) + "\n"
        )
        (d / "bad.asc").write_text("ncols 3\nnrows 3\ncellsize 1\n1 2\n")
        (d / "bad.tif").write_bytes(b"II*\x00garbage")
        (d / "world.tif").write_bytes(b"MM\x00*" + bytes(64))
        (d / "world.txt").write_text("1 2 3\n")
        (d / "adir").mkdir(exist_ok=True)
        rng = np.random.default_rng(0)
        cloud = np.column_stack((rng.uniform(-20, 20, (4000, 2)), rng.normal(0, 0.02, 4000)))
        np.save(d / "cloud.npy", cloud)
        from lsd.io import write_ply

        write_ply(d / "cloud.ply", cloud, binary=True)
        write_ply(d / "cloud_ascii.ply", cloud[:500], binary=False)
        depth = np.full((120, 160), 10.0) + rng.normal(0, 0.01, (120, 160))
        np.save(d / "depth.npy", depth)
        import cv2

        cv2.imwrite(str(d / "depth.png"), (depth * 1000).astype(np.uint16))
        try:
            import laspy

            header = laspy.LasHeader(point_format=3, version="1.2")
            las = laspy.LasData(header)
            las.x, las.y, las.z = cloud[:, 0], cloud[:, 1], cloud[:, 2]
            las.write(str(d / "cloud.las"))
            self.laspy = True
        except Exception:  # noqa: BLE001 - the las extra is optional
            self.laspy = False
        good = MISSIONS / "demo.yaml"
        doc = yaml.safe_load(good.read_text())
        doc["time_limit"] = FLY_TIME_LIMIT
        (d / "demo.yaml").write_text(yaml.safe_dump(doc))
        self.mission = d / "demo.yaml"

    def mission_names(self) -> list[str]:
        return [str(self.mission), str(self.dir / "case.yaml"), str(self.dir / "missing.yaml"),
                str(self.dir / "adir"), "/dev/null", str(self.dir / "cloud.npy"),
                str(MISSIONS / "demo.yaml")]


def _npy_bytes(array: np.ndarray, allow_pickle: bool = False) -> bytes:
    buf = io.BytesIO()
    np.save(buf, array, allow_pickle=allow_pickle)
    return buf.getvalue()


@st.composite
def arrays(draw: Any) -> np.ndarray:
    shape = draw(st.sampled_from([(), (0,), (5,), (0, 3), (1, 3), (7, 3), (300, 3), (300, 2),
                                  (300, 4), (3, 300), (2, 2), (1, 1), (40, 30), (1, 400),
                                  (5, 5, 3), (2, 3, 4, 5), (2000, 3)]))
    dtype = draw(st.sampled_from(["float64", "float32", "float16", "int8", "uint16", "int64",
                                  "bool", "complex128", "U3", "datetime64[s]", "object",
                                  "f8,f8,f8"]))
    fill = draw(st.sampled_from(["random", "nan", "inf", "zero", "huge", "negative", "mixed"]))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    size = int(np.prod(shape)) if shape else 1
    base = {
        "random": rng.normal(0, 10, size), "nan": np.full(size, np.nan),
        "inf": np.full(size, np.inf), "zero": np.zeros(size), "huge": np.full(size, 1e300),
        "negative": -np.abs(rng.normal(0, 10, size)),
        "mixed": rng.choice([np.nan, np.inf, -np.inf, 0.0, 1e300, 1.0], size),
    }[fill].reshape(shape)
    if dtype == "object":
        out = np.empty(shape, dtype=object)
        out[...] = None
        return out
    if dtype == "f8,f8,f8":
        return np.zeros(shape, dtype=dtype)
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            return base.astype(dtype)
        except (ValueError, TypeError, OverflowError):
            return np.zeros(shape, dtype=dtype)


def _damage(draw: Any, data: bytes) -> bytes:
    kind = draw(st.sampled_from(["none", "none", "truncate", "flip", "garbage", "header"]))
    if kind == "truncate" and data:
        return data[: draw(st.integers(0, len(data) - 1))]
    if kind == "flip" and data:
        i = draw(st.integers(0, len(data) - 1))
        return data[:i] + bytes([data[i] ^ 0xFF]) + data[i + 1:]
    if kind == "garbage":
        return draw(st.binary(max_size=200))
    if kind == "header" and data:
        return data[:8] + b"\xff" * 16 + data[24:]
    return data


@st.composite
def npy_files(draw: Any) -> bytes:
    array = draw(arrays())
    data = _npy_bytes(array, allow_pickle=array.dtype == object)
    return _damage(draw, data)


@st.composite
def ply_files(draw: Any) -> bytes:
    n = draw(st.sampled_from([0, 1, 3, 50, 10**12, -1]))
    fmt = draw(st.sampled_from(["ascii 1.0", "binary_little_endian 1.0",
                                "binary_big_endian 1.0", "foo 1.0"]))
    props = draw(st.sampled_from([
        ["float x", "float y", "float z"], ["double x", "double y", "double z", "uchar red"],
        ["float x", "float y"], ["list uchar int vertex_indices"], ["int8 x", "float y", "z"],
        ["float64 x", "float64 y", "float64 z"], []]))
    header = ["ply", f"format {fmt}", f"element vertex {n}"]
    header += [f"property {p}" for p in props]
    if draw(st.booleans()):
        header.append("element face 2")
        header.append("property list uchar int vertex_indices")
    if draw(st.integers(0, 5)):
        header.append("end_header")
    body_rows = max(0, min(n, 60)) if isinstance(n, int) else 0
    if fmt.startswith("ascii"):
        body = "\n".join(" ".join(draw(st.sampled_from(["1", "nan", "-inf", "x", "1e400", ""]))
                                  for _ in range(max(1, len(props))))
                         for _ in range(body_rows)).encode()
    else:
        body = draw(st.binary(max_size=body_rows * 24 + 8))
    return _damage(draw, ("\n".join(header) + "\n").encode() + body)


@st.composite
def png_files(draw: Any) -> bytes:
    import cv2

    shape = draw(st.sampled_from([(1, 1), (4, 4), (60, 80), (60, 80, 3), (60, 80, 4), (1, 2000)]))
    dtype = draw(st.sampled_from([np.uint8, np.uint16]))
    fill = draw(st.sampled_from([0, 1, 65535, None]))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    image = (rng.integers(0, 60000, shape) if fill is None else np.full(shape, fill)).astype(dtype)
    ok, buf = cv2.imencode(".png", image)
    return _damage(draw, bytes(buf) if ok else b"")


@st.composite
def asc_files(draw: Any) -> bytes:
    ncols = draw(st.sampled_from(["3", "0", "-3", "1e9", "x", "3.5", "nan"]))
    nrows = draw(st.sampled_from(["3", "1", "0", "99999999999", "y"]))
    cell = draw(st.sampled_from(["1", "0", "-1", "nan", "inf", "1e-300", "1e300", "z"]))
    header = [f"ncols {ncols}", f"nrows {nrows}", "xllcorner 0", "yllcorner 0",
              f"cellsize {cell}"]
    if draw(st.booleans()):
        header.append(f"NODATA_value {draw(st.sampled_from(['-9999', '0', 'nan']))}")
    body = "\n".join(
        " ".join(draw(st.sampled_from(["0", "1", "-9999", "nan", "1e308", "x", ""]))
                 for _ in range(3)) for _ in range(draw(st.integers(0, 4))))
    return _damage(draw, ("\n".join(header) + "\n" + body + "\n").encode())


@st.composite
def las_files(draw: Any, files: Files) -> bytes:
    data = (files.dir / "cloud.las").read_bytes() if files.laspy else b"LASF"
    kind = draw(st.sampled_from(["truncate", "flip", "count", "garbage", "scale"]))
    if kind == "count" and len(data) > 111:
        return data[:107] + (2**32 - 1).to_bytes(4, "little") + data[111:]
    if kind == "scale" and len(data) > 155:
        return data[:131] + np.array([0.0, np.nan, np.inf], "<f8").tobytes() + data[155:]
    if kind == "garbage":
        return b"LASF" + draw(st.binary(max_size=400))
    return _damage(draw, data)


# --------------------------------------------------------------------------------------
# Argument lists


def closed_port() -> int:
    """A local TCP port nobody listens on (bound, then closed)."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def urls(port: int) -> st.SearchStrategy[str]:
    return st.sampled_from([
        "sim://", "sim://px4", "sim://ardupilot?seed=3", "sim://inav", "sim", "sim:/", "sim://?x=1",
        "sim://?seed=-1", "sim://?seed=99999999999", "bogus://x", "udp:", "udp:not-an-address",
        "tcp:127.0.0.1:99999", "tcp:127.0.0.1:-1", f"tcp:127.0.0.1:{port}", "tcp::5760", "",
        " ", "serial", "/dev/ttyNOPE", "/dev/ttyNOPE,abc", "/dev/ttyNOPE,0", "COM99,57600",
        "udpin:999.1.1.1:14550", "tcp:[::1]:x", "\x00", "http://example.invalid", "tcp:a b:1",
    ])


def option_values(action: Any, files: Files, port: int) -> st.SearchStrategy[list[str]]:
    """Values for one argparse option (a list of argv words after the option string)."""
    option = action.option_strings[0] if action.option_strings else ""
    if action.nargs == 0:
        return st.just([])
    if action.choices:
        words = st.one_of(st.sampled_from(sorted(map(str, action.choices))),
                          st.sampled_from(["", "ARDUPILOT", "none", "🚁"]))
    elif option in ("--connect",):
        words = urls(port)
    elif option in ("--out", "--dot", "--tlog"):
        words = st.sampled_from(["out", "o/p/q", str(files.dir / "cloud.npy"), "/proc/nope/x",
                                 "", ".", "adir", "/dev/null/x"])
    elif option in ("--lidar", "--depth", "--pose"):
        words = st.sampled_from(["cloud.npy", "cloud.ply", "cloud_ascii.ply", "cloud.las",
                                 "depth.npy", "depth.png", "case.npy", "case.ply", "case.png",
                                 "case.las", "case.laz", "missing.npy", "adir", "/dev/null",
                                 "cloud.xyz", "", "1,2,3,4", "0,0,10,0", "nan,0,0,0",
                                 "1,2", "pose.npy"])
    elif option == "--set":
        words = st.one_of(
            st.sampled_from(["landing.verification_altitude=5", "lsm.capacity=1e23",
                             "lsm.capacity=true", "waypoints=[[1e39,0,30]]", "seed=-5",
                             "perception.rate=100", "=5", "x", "a..b=1", "sites.9.x=1",
                             "rock_density=0.3", "size=[200,200]", "size=[1e9,1e9]",
                             "cell_size=1e-9", "path=world.asc", "kind=file", "relief_rms=nan",
                             "time_limit=1e308", "tick_rate=1e-300", "name=🚁",
                             "vehicle.connection=bogus://x", "landing.search_rectangle=[0,3]",
                             "world.kind=urban", "perception.detector=lidar_pca",
                             "lsm.capacity=1000000000", "waypoints=[]", "sites=[{x: 1}]",
                             "crater_density=1e9", "scarp_count=100", "tree_density=1e9",
                             "perception.camera.width=4096", "sitl.physics_step=1e-9"]),
            st.tuples(st.sampled_from(["lsm.capacity", "seed", "cruise_altitude", "tick_rate",
                                       "size", "cell_size", "rock_density", "home_clear_radius",
                                       "landing.landing_retries", "perception.rate"]),
                      cli_numbers()).map(lambda kv: f"{kv[0]}={kv[1]}"),
        )
    elif option == "--vary":
        words = st.sampled_from(["seed=1,2", "lsm.capacity=1:3", "x=1", "seed=", "=1",
                                 "landing.verification_altitude=1e308,5", "seed=1:1e9:3",
                                 "seed=-1,2", "a=[", "lsm.capacity=true,1",
                                 "landing.verification_duration=4,8"])
    elif option == "--scheduler":
        words = st.sampled_from(["tcp://127.0.0.1:1", "tcp://", "bogus", ""])
    elif option in ("--home",):
        words = st.sampled_from(["47,8,400", "91,0,0", "0,0,1e9", "nan,0,0", "1,2", "a,b,c",
                                 "-35.36,149.16,584", ""])
    elif option in ("--tcp", "--udp", "--udp-out"):
        words = st.sampled_from(["127.0.0.1:0", "127.0.0.1:99999", "nohost", ":", "x:y",
                                 "999.0.0.1:0", "127.0.0.1:0>127.0.0.1:1", ">", ""])
    elif option in ("--signing-key-env", ):
        words = st.sampled_from(["NOPE_NOT_SET", "PATH", "", "1BAD", "HOME"])
    elif option == "--depth-at":
        words = st.sampled_from(["0,0,10", "0,0,-1", "1e9,0,10", "nan,0,1", "0,0,100,45",
                                 "0,0", "a,b,c", "0,0,1e308"])
    elif option == "--compare":
        return st.lists(st.sampled_from(files.mission_names()), min_size=0, max_size=3)
    else:
        words = cli_numbers()
    return words.map(lambda w: [w])


def _actions(command: str) -> tuple[list[Any], list[Any]]:
    from autonomy.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if hasattr(a, "choices") and a.choices
               and command in a.choices).choices[command]
    options = [a for a in sub._actions if a.option_strings and a.dest != "help"]
    positionals = [a for a in sub._actions if not a.option_strings]
    return options, positionals


COMMANDS = ("fly", "demo", "validate", "tree", "campaign", "sitl", "detect", "link", "terrain",
            "replay")


@st.composite
def argument_lists(draw: Any, command: str, files: Files, port: int) -> list[str]:
    """An argument list for ``lander COMMAND`` built from its argparse definition."""
    options, positionals = _actions(command)
    argv = [command]
    for _action in positionals:
        if command == "link":
            argv.append(draw(urls(port)))
        elif draw(st.integers(0, 9)):
            argv.append(draw(st.sampled_from(files.mission_names())))
    chosen = draw(st.lists(st.sampled_from(options), max_size=5, unique_by=lambda a: a.dest)
                  ) if options else []
    for action in chosen:
        argv.append(draw(st.sampled_from(action.option_strings)))
        argv += draw(option_values(action, files, port))
    if draw(st.integers(0, 9)) == 0:
        argv.append(draw(st.sampled_from(["--nope", "-x", "extra", "--", "-", "--seed"])))
    return _keep_short(argv, files, port)


def _keep_short(argv: list[str], files: Files, port: int) -> list[str]:
    """Make argument lists that would be valid and long by design short (see module doc)."""
    command = argv[0]

    def has(flag: str) -> bool:
        return any(a == flag or a.startswith(flag + "=") for a in argv)

    if command == "sitl":
        argv += ["--duration", "0.5"] if not has("--duration") else []
        argv += ["--speedup", "5"] if not has("--speedup") else []
        if not (has("--tcp") or has("--udp") or has("--udp-out")):
            argv += ["--tcp", "127.0.0.1:0"]
        argv = _replace_small(argv, "--duration", 5.0, "0.5")
        argv = _replace_small(argv, "--speedup", None, "5", low=1.0)
    elif command == "link":
        live = not argv[1].startswith("sim:") if len(argv) > 1 else False
        if not has("--duration"):
            argv += ["--duration", "0.5" if live else "3"]
        argv = _replace_small(argv, "--duration", 1.0 if live else 60.0, "0.5")
    elif command == "campaign":
        argv = _replace_small(argv, "--runs", 2.0, "1")
        if not has("--runs"):
            argv += ["--runs", "1"]
        argv += ["--workers", "1", "--connect-timeout", "1"]
        argv = _drop_option(argv, "--workers", keep_last=True)
        argv = _drop_option(argv, "--connect-timeout", keep_last=True)
    elif command == "terrain":
        argv = _replace_small(argv, "--seed", None, "1")
    return argv


def _replace_small(argv: list[str], flag: str, high: float | None, value: str,
                   low: float | None = None) -> list[str]:
    """Replace a valid number after ``flag`` above ``high`` (or below ``low``) by ``value``."""
    out = list(argv)
    for i, word in enumerate(out[:-1]):
        if word == flag:
            try:
                number = float(out[i + 1])
            except ValueError:
                continue
            if not math.isfinite(number) or number <= 0:
                continue
            if (high is not None and number > high) or (low is not None and number < low):
                out[i + 1] = value
    return out


def _drop_option(argv: list[str], flag: str, keep_last: bool) -> list[str]:
    where = [i for i, a in enumerate(argv) if a == flag]
    drop = set()
    for i in where[:-1] if keep_last else where:
        drop |= {i, i + 1}
    return [a for i, a in enumerate(argv) if i not in drop]


# --------------------------------------------------------------------------------------
# Cases as the harness runs them


@dataclass
class Case:
    """One input: the argument list and the files it needs written first."""

    entry: str
    argv: list[str]
    writes: dict[str, bytes] = field(default_factory=dict)
    deadline: float | None = None


def write_case(case: Case, files: Files) -> None:
    for name, data in case.writes.items():
        (files.dir / name).write_bytes(data)


@st.composite
def validate_cases(draw: Any, files: Files, source: str) -> Case:
    docs = schema_documents() if source == "schema" else mutated_documents()
    text = draw(mission_texts(docs))
    command = draw(st.sampled_from(["validate", "validate", "tree"]))
    return Case(f"{command} ({source} missions)", [command, str(files.dir / "case.yaml")],
                {"case.yaml": text})


@st.composite
def fly_cases(draw: Any, files: Files) -> Case:
    doc = draw(mutated_documents(fly=True))
    text = _dump(doc).encode("utf-8", errors="surrogateescape")
    argv = ["fly", str(files.dir / "case.yaml"), "--quiet", "--out", "flyout"]
    if draw(st.integers(0, 4)) == 0:
        argv += ["--seed", draw(cli_numbers())]
    return Case("fly (mutated missions)", argv, {"case.yaml": text}, deadline=180.0)


@st.composite
def cli_cases(draw: Any, files: Files, port: int, command: str | None = None) -> Case:
    command = command or draw(st.sampled_from(COMMANDS))
    argv = draw(argument_lists(command, files, port))
    writes = {"case.yaml": draw(mission_texts(mutated_documents()))}
    return Case(f"{command} (argument lists)", argv, writes,
                deadline=180.0 if command in ("fly", "demo", "campaign", "terrain") else None)


@st.composite
def detect_cases(draw: Any, files: Files) -> Case:
    kind = draw(st.sampled_from(["npy_lidar", "ply", "las", "laz", "npy_depth", "png"]))
    if kind in ("npy_lidar", "npy_depth"):
        name, data = "case.npy", draw(npy_files())
    elif kind == "ply":
        name, data = "case.ply", draw(ply_files())
    elif kind in ("las", "laz"):
        name, data = f"case.{kind}", draw(las_files(files))
    else:
        name, data = "case.png", draw(png_files())
    argv = ["detect", "--out", "detect_out"]
    if kind in ("npy_depth", "png"):
        argv += ["--depth", name, "--fx", "100", "--fy", "100", "--cx", "40", "--cy", "30"]
        if draw(st.booleans()):
            argv += ["--pose", draw(st.sampled_from(["0,0,10,0", "pose.npy", "1,2"]))]
    else:
        argv += ["--lidar", name]
        if draw(st.booleans()):
            argv += ["--seeding", "grid"]
    pose = draw(npy_files()) if "pose.npy" in argv else None
    writes = {name: data}
    if pose is not None:
        writes["pose.npy"] = pose
    return Case(f"detect ({kind} files)", argv, writes)


@st.composite
def world_file_cases(draw: Any, files: Files) -> Case:
    kind = draw(st.sampled_from(["npy", "asc", "tif"]))
    data = {"npy": npy_files, "asc": asc_files}.get(kind, lambda: st.binary(max_size=300))()
    name = f"worldcase.{kind}"
    doc = copy.deepcopy(base_missions()[0])
    doc["world"] = {"kind": "file", "path": name}
    if kind == "npy":
        doc["world"]["source_cell_size"] = draw(st.sampled_from([0.5, 1.0, 2.0, 1e-3]))
    command = draw(st.sampled_from(["validate", "validate", "fly"]))
    argv = [command, str(files.dir / "case.yaml")]
    if command == "fly":
        argv += ["--quiet", "--out", "flyout"]
    return Case(f"{command} (world: file, {kind})", argv,
                {name: draw(data), "case.yaml": _dump(doc).encode()},
                deadline=180.0 if command == "fly" else None)


def run_case(runner: Runner, files: Files, case: Case) -> Result:
    write_case(case, files)
    return runner.run(case.argv, case.deadline)
