"""The ``--vary KEY=SPEC`` grammar of campaigns.

``KEY`` is a dotted mission key (``landing.verification_altitude``, ``sitl.wind.speed``).
``SPEC`` is one of:

- a list ``V1,V2,...``, read as a YAML flow sequence: ``2.5`` is a number, ``true`` a
  boolean, ``mars`` a string, ``null`` None and ``[40,30]`` a list, for settings that are
  lists (``2.5,5,10``; ``[40,30],[80,60]``; a single value is a list of one). Quote a
  string that contains ``:`` or ``,``;
- an integer range ``A:B`` with integers ``A <= B``: every integer from A to B inclusive
  (``0:8`` is 0, 1, ..., 8);
- an evenly spaced range ``A:B:N``: N >= 2 values from A to B inclusive, like
  ``numpy.linspace`` (``0:8:5`` is 0, 2, 4, 6, 8; integers stay integers when every value
  is whole and A and B are written as integers).

Several ``--vary`` options form the cartesian product of their values (the variants).
"""

from __future__ import annotations

import itertools
import math
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import yaml

from autonomy.errors import UserError

_KEY = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*$")
_INT = re.compile(r"^[+-]?\d+$")


@dataclass(frozen=True)
class Vary:
    """One ``--vary`` option: a mission key and the values it takes, in order."""

    key: str
    values: tuple[Any, ...]


@dataclass(frozen=True)
class Variant:
    """One combination of varied values; ``overrides`` maps mission keys to values."""

    index: int
    overrides: dict[str, Any]

    @property
    def label(self) -> str:
        """Short human name, e.g. ``verification_altitude=5 wind.speed=2``; ``base`` if none."""
        if not self.overrides:
            return "base"
        return " ".join(f"{_short(k)}={_fmt(v, short=True)}" for k, v in self.overrides.items())

    @property
    def key(self) -> str:
        """Canonical identity of the variant (order-free), used to match recorded runs."""
        return ",".join(f"{k}={_fmt(v)}" for k, v in sorted(self.overrides.items()))


def _short(key: str) -> str:
    parts = key.split(".")
    return ".".join(parts[-2:]) if len(parts) > 2 else key


def _fmt(value: Any, short: bool = False) -> str:
    if isinstance(value, float):
        if value.is_integer() and abs(value) < 1e15:
            return str(int(value))
        return f"{value:.4g}" if short else repr(value)
    return str(value)


def _number(text: str, what: str) -> int | float:
    text = text.strip()
    if _INT.match(text):
        return int(text)
    try:
        value = float(text)
    except ValueError:
        raise UserError(f"{what}: {text!r} is not a number") from None
    if not math.isfinite(value):
        raise UserError(f"{what}: {text!r} is not a finite number")
    return value


def _numeric(value: Any) -> Any:
    """YAML 1.1 reads ``1e3`` as a string: make such strings numbers."""
    if isinstance(value, str):
        try:
            number = float(value)
        except ValueError:
            return value
        return number if math.isfinite(number) else value
    return value


def _list(spec: str, what: str) -> tuple[Any, ...]:
    try:
        values = yaml.safe_load(f"[{spec}]")
    except yaml.YAMLError:
        raise UserError(f"{what}: cannot read {spec!r} as a comma-separated list") from None
    if any(isinstance(v, dict) for v in values):
        raise UserError(f"{what}: {spec!r}: a value cannot be a mapping")
    return tuple(_numeric(v) for v in values)


def parse_values(spec: str, what: str = "--vary") -> tuple[Any, ...]:
    """Values of one SPEC (a list, ``A:B`` or ``A:B:N``, see the module docstring)."""
    spec = spec.strip()
    if not spec:
        raise UserError(f"{what}: no values after '='")
    if ":" not in spec or any(c in spec for c in ",[]'\""):
        return _list(spec, what)
    parts = spec.split(":")
    if len(parts) not in (2, 3):
        raise UserError(f"{what}: range {spec!r} must be A:B or A:B:N")
    start, stop = (_number(p, what) for p in parts[:2])
    if len(parts) == 2:
        if not (isinstance(start, int) and isinstance(stop, int)):
            raise UserError(f"{what}: range {spec!r} without a count needs integers (or A:B:N)")
        if stop < start:
            raise UserError(f"{what}: range {spec!r} runs backwards")
        return tuple(range(start, stop + 1))
    count_text = parts[2].strip()
    if not _INT.match(count_text) or int(count_text) < 2:
        raise UserError(f"{what}: range {spec!r}: the count N must be an integer >= 2")
    values = np.linspace(start, stop, int(count_text))
    if isinstance(start, int) and isinstance(stop, int) and np.all(values == np.round(values)):
        return tuple(int(v) for v in np.round(values))
    return tuple(float(v) for v in values)


def parse_vary(option: str) -> Vary:
    """Parse one ``KEY=SPEC`` option; raises :class:`UserError` on malformed input."""
    key, sep, spec = option.partition("=")
    key = key.strip()
    if not sep:
        raise UserError(f"--vary {option!r}: expected KEY=SPEC")
    if not _KEY.match(key):
        raise UserError(f"--vary {option!r}: {key!r} is not a dotted mission key")
    values = parse_values(spec, what=f"--vary {key}")
    if len(set(map(repr, values))) != len(values):
        raise UserError(f"--vary {key}: repeated values in {spec!r}")
    return Vary(key, values)


def variants(varies: Sequence[Vary]) -> list[Variant]:
    """The cartesian product of the varied values, in option order (one variant if none)."""
    keys = [v.key for v in varies]
    duplicated = sorted({k for k in keys if keys.count(k) > 1})
    if duplicated:
        raise UserError(f"--vary: key {duplicated[0]} given more than once")
    combos: Iterable[tuple[Any, ...]] = itertools.product(*(v.values for v in varies))
    return [Variant(i, dict(zip(keys, combo, strict=True))) for i, combo in enumerate(combos)]
