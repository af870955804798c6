"""Reading rig, probe and scene TOML files with errors that say exactly what is wrong.

A :class:`Table` wraps one TOML table and hands out typed, range-checked values.
Every error names the file, the key path (``link[3].alpha_deg``), the value found
and what is allowed. Keys that were never asked for are reported by
:meth:`Table.finish`, so a misspelt key is an error instead of being ignored.

Rig files live in ``rigs/<kind>/<name>.toml``; :func:`resolve_rig` turns a bare
name or a path into a file.
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Any, Iterable

import numpy as np

from ..errors import ConfigError
from ..kinematics.euler import pose_from_xyz_yzz, pose_to_xyz_yzz

RIGS_DIR = Path(__file__).resolve().parents[3] / "rigs"

_MISSING = object()


def resolve_rig(kind: str, name_or_path: str | Path) -> Path:
    """File for a rig: a bare name under ``rigs/<kind>/`` or a path to a .toml file."""
    text = str(name_or_path)
    p = Path(text).expanduser()
    looks_like_path = p.suffix == ".toml" or any(sep in text for sep in ("/", "\\"))
    what = kind[:-1] if kind.endswith("s") else kind
    if looks_like_path:
        if p.is_dir():
            raise ConfigError(f"{p}: a folder, not a {what} file (.toml)")
        if not p.is_file():
            bundled = RIGS_DIR / kind / p.name
            hint = (f"; the bundled {what} '{p.stem}' is named without .toml or a folder: {p.stem}"
                    if p.suffix == ".toml" and bundled.is_file() and not p.is_absolute() else "")
            raise ConfigError(f"{p}: no such file{hint}")
        return p
    candidate = RIGS_DIR / kind / f"{text}.toml"
    if candidate.is_file():
        return candidate
    known = ", ".join(available_rigs(kind)) or "none"
    if p.is_dir():
        raise ConfigError(f"{p}: a folder, not a {what} file (.toml), and not one of the bundled {kind} ({known})")
    raise ConfigError(f"unknown {what} '{text}': not a file, and not one of the bundled {kind} ({known})")


def available_rigs(kind: str) -> list[str]:
    """Names of the bundled rig files of a kind ('robots', 'probes', 'scenes')."""
    return sorted(p.stem for p in (RIGS_DIR / kind).glob("*.toml"))


def load_toml(path: str | Path) -> "Table":
    """Parse a TOML file into a :class:`Table`; syntax errors become ConfigError."""
    path = Path(path)
    try:
        with path.open("rb") as fh:
            data = tomllib.load(fh)
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such file") from None
    except tomllib.TOMLDecodeError as exc:
        if _starts_with_bom(path):
            raise ConfigError(f"{path}: starts with a byte-order mark (as some Windows editors save UTF-8), which "
                              f"TOML does not allow; save it as UTF-8 without one") from None
        raise ConfigError(f"{path}: not valid TOML: {exc}") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{path}: not UTF-8 text (byte {exc.start} cannot be decoded); TOML files are UTF-8") \
            from None
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read: {exc.strerror or exc}") from None
    return Table(data, str(path))


def _starts_with_bom(path: Path) -> bool:
    try:
        with path.open("rb") as fh:
            return fh.read(3) == b"\xef\xbb\xbf"
    except OSError:
        return False


def _describe(value: Any) -> str:
    if isinstance(value, dict):
        return "a table"
    if isinstance(value, list):
        return f"a list of {len(value)}"
    return repr(value)


class Table:
    """One TOML table with typed, validated access and unknown-key detection."""

    def __init__(self, data: dict, file: str, prefix: str = ""):
        self.data = data
        self.file = file
        self.prefix = prefix
        self._used: set[str] = set()

    # -- errors ---------------------------------------------------------------
    def key_path(self, key: str) -> str:
        return f"{self.prefix}{key}"

    def error(self, key: str, message: str) -> ConfigError:
        return ConfigError(f"{self.file}: {self.key_path(key)}: {message}")

    def table_error(self, message: str) -> ConfigError:
        """An error about the table as a whole (e.g. two keys that do not fit together)."""
        return ConfigError(f"{self.file}: [{self.prefix.rstrip('.') or 'top level'}]: {message}")

    def _get(self, key: str, default: Any) -> Any:
        self._used.add(key)
        if key in self.data:
            return self.data[key]
        if default is _MISSING:
            raise self.error(key, "missing (required)")
        return default

    def has(self, key: str) -> bool:
        """Whether the file gives ``key``; asking names it among the keys this table takes
        (:meth:`finish`'s list of what is allowed), given or not."""
        self._used.add(key)
        return key in self.data

    def allow(self, *keys: str) -> None:
        """Name ``keys`` among those this table takes, for :meth:`finish`'s list of what is
        allowed, where the file may leave them all out (one of two ways to say a thing)."""
        self._used.update(keys)

    # -- scalars --------------------------------------------------------------
    def number(self, key: str, default: Any = _MISSING, *, lo: float | None = None,
               hi: float | None = None, lo_open: bool = False, hi_open: bool = False,
               nonzero: bool = False, inf_ok: bool = False) -> float:
        """A finite number in [lo, hi] (or open ends); ints and floats accepted, bools not.
        An absent key gives ``default`` unchecked (so None can mean "derive it"). ``inf_ok``:
        ``inf`` (no limit) is taken too."""
        if key not in self.data and default is not _MISSING:
            self._used.add(key)
            return default
        value = self._get(key, default)
        if inf_ok and isinstance(value, float) and value == math.inf:
            return value
        return self._check_number(key, value, lo, hi, lo_open, hi_open, nonzero)

    def _check_number(self, key, value, lo, hi, lo_open, hi_open, nonzero, where: str = "") -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.error(key, f"{where}{_describe(value)} is not a number")
        try:
            v = float(value)
        except OverflowError:  # a TOML integer of 309 digits or more
            v = math.inf if value > 0 else -math.inf
        if not math.isfinite(v):
            raise self.error(key, f"{where}{value} is not allowed; it must be a finite number")
        bad_lo = lo is not None and (v <= lo if lo_open else v < lo)
        bad_hi = hi is not None and (v >= hi if hi_open else v > hi)
        if bad_lo or bad_hi or (nonzero and v == 0.0):
            raise self.error(key, f"{where}{value} is out of range; allowed {_range_text(lo, hi, lo_open, hi_open, nonzero)}")
        return v

    def integer(self, key: str, default: Any = _MISSING, *, lo: int | None = None, hi: int | None = None) -> int:
        value = self._get(key, default)
        if isinstance(value, bool) or not isinstance(value, int):
            allowed = "" if lo is None and hi is None else \
                f" (allowed: a whole number {_range_text(lo, hi, False, False, False)})"
            raise self.error(key, f"{_describe(value)} is not an integer{allowed}")
        if (lo is not None and value < lo) or (hi is not None and value > hi):
            raise self.error(key, f"{value} is out of range; allowed {_range_text(lo, hi, False, False, False)}")
        return value

    def string(self, key: str, default: Any = _MISSING, *, choices: Iterable[str] | None = None) -> str:
        value = self._get(key, default)
        if not isinstance(value, str):
            raise self.error(key, f"{_describe(value)} is not a string")
        if choices is not None:
            choices = list(choices)
            if value not in choices:
                raise self.error(key, f"'{value}' is not one of: {', '.join(choices)}")
        return value

    def strings(self, key: str, default: Any = _MISSING) -> list[str]:
        """A list of strings (may be empty)."""
        value = self._get(key, default)
        if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) for v in value):
            raise self.error(key, f"{_describe(value)}: expected a list of strings")
        return list(value)

    def boolean(self, key: str, default: Any = _MISSING) -> bool:
        value = self._get(key, default)
        if not isinstance(value, bool):
            raise self.error(key, f"{_describe(value)} is not true or false")
        return value

    def numbers(self, key: str, count: int, default: Any = _MISSING, *, lo: float | None = None,
                hi: float | None = None) -> np.ndarray:
        """A list of exactly ``count`` finite numbers, each in [lo, hi]."""
        value = self._get(key, default)
        if not isinstance(value, (list, tuple)) or len(value) != count:
            raise self.error(key, f"{_describe(value)}: expected a list of {count} numbers")
        out = [self._check_number(key, v, lo, hi, False, False, False, where=f"element {i}: ")
               for i, v in enumerate(value)]
        return np.array(out, dtype=np.float64)

    def number_list(self, key: str, default: Any = _MISSING, *, lo: float | None = None,
                    hi: float | None = None, lo_open: bool = False, min_len: int = 1) -> np.ndarray:
        """A list of at least ``min_len`` finite numbers, each in [lo, hi] (a default is taken as is)."""
        if key not in self.data and default is not _MISSING:
            self._used.add(key)
            return np.asarray(default, dtype=np.float64)
        value = self._get(key, default)
        if not isinstance(value, (list, tuple)) or len(value) < min_len:
            raise self.error(key, f"{_describe(value)}: expected a list of at least {min_len} number(s)")
        return np.array([self._check_number(key, v, lo, hi, lo_open, False, False, where=f"element {i}: ")
                         for i, v in enumerate(value)], dtype=np.float64)

    # -- nested ---------------------------------------------------------------
    def table(self, key: str, default: Any = _MISSING) -> "Table | None":
        value = self._get(key, default)
        if value is None:
            return None
        if not isinstance(value, dict):
            raise self.error(key, f"{_describe(value)}: expected a table [{self.key_path(key)}]")
        return Table(value, self.file, f"{self.key_path(key)}.")

    def tables(self, key: str) -> list["Table"]:
        """An array of tables ([[key]] in TOML)."""
        value = self._get(key, _MISSING)
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            raise self.error(key, f"{_describe(value)}: expected [[{key}]] tables")
        return [Table(v, self.file, f"{self.key_path(key)}[{i + 1}].") for i, v in enumerate(value)]

    def pose(self, key: str, *, max_offset_mm: float = 1e7, base: np.ndarray | None = None) -> np.ndarray:
        """Optional rigid transform table ``{xyz_mm = [x, y, z], yzz_deg = [yaw, pitch, roll]}``.

        A missing table gives ``base`` (default: the identity); a missing key, ``base``'s
        offset or angles (so a table that overrides one keeps the other). Returns (4, 4), mm.
        """
        base = np.eye(4) if base is None else np.asarray(base, dtype=np.float64)
        t = self.table(key, default=None)
        if t is None:
            return base.copy()
        xyz0, yzz0 = pose_to_xyz_yzz(base)
        xyz = t.numbers("xyz_mm", 3, default=[float(v) for v in xyz0], lo=-max_offset_mm, hi=max_offset_mm)
        yzz = t.numbers("yzz_deg", 3, default=[float(v) for v in np.degrees(yzz0)], lo=-720.0, hi=720.0)
        t.finish()
        return pose_from_xyz_yzz(xyz, np.radians(yzz))

    def finish(self) -> None:
        """Raise for keys present in the file that nothing asked for (likely misspelt)."""
        unknown = [k for k in self.data if k not in self._used]
        if unknown:
            allowed = ", ".join(sorted(self._used)) or "none"
            raise ConfigError(f"{self.file}: unknown key {self.key_path(unknown[0])!s}"
                              f"{' (and ' + str(len(unknown) - 1) + ' more)' if len(unknown) > 1 else ''}; "
                              f"allowed here: {allowed}")


def _range_text(lo, hi, lo_open, hi_open, nonzero) -> str:
    parts = []
    if lo is not None and hi is not None:
        parts.append(f"{'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}")
    elif lo is not None:
        parts.append(f"{'>' if lo_open else '≥'} {lo:g}")
    elif hi is not None:
        parts.append(f"{'<' if hi_open else '≤'} {hi:g}")
    if nonzero:
        parts.append("not 0")
    return ", ".join(parts) or "any finite number"
