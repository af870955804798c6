"""Property-based fuzzing of the config and rig loaders: whatever the file holds, loading it
either works or raises the project's own error with a message, never anything else.

Files are made by mutating the bundled ones (a value swapped for a wrong one, a line
dropped or doubled, the file cut short, bytes thrown in) and from arbitrary text.
"""

from __future__ import annotations

import itertools
import re
import tempfile
from pathlib import Path

import pytest

hypothesis = pytest.importorskip("hypothesis", reason="installed by the README's set-up")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from addon.core.config.rigs import load_probe, load_robot  # noqa: E402
from addon.core.config.scan import load_scan_config  # noqa: E402
from addon.core.errors import ScannerError  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
FILES = {
    "scene": [REPO / "rigs" / "scenes" / n for n in ("demo.toml", "step_block.toml", "cylinder_realistic.toml")],
    "robot": sorted((REPO / "rigs" / "robots").glob("*.toml")),
    "probe": sorted((REPO / "rigs" / "probes").glob("*.toml")),
}
LOADERS = {"scene": load_scan_config, "robot": load_robot, "probe": load_probe}
WRONG_VALUES = ["nan", "inf", "-inf", "-1", "0", "1e308", "-1e308", "3.5", '"x"', '""', "true", "[]", "[1, 2]",
                "[nan, 0, 0]", "{}", '"../../etc/passwd"', "1979-05-27", "[[1], [2]]", '"\u00e9\u00e8"']
VALUE = re.compile(r"=\s*([^\n#]+)")
_counter = itertools.count()
_folder = Path(tempfile.mkdtemp(prefix="loader-fuzz-"))


@st.composite
def mutated(draw, kind: str) -> bytes:
    text = draw(st.sampled_from(FILES[kind])).read_text()
    for _ in range(draw(st.integers(1, 4))):
        op = draw(st.sampled_from(["value", "drop", "double", "cut", "bytes", "key"]))
        lines = text.splitlines(keepends=True)
        if not lines:
            break
        i = draw(st.integers(0, len(lines) - 1))
        if op == "value" and VALUE.search(lines[i]):
            lines[i] = VALUE.sub(lambda m: "= " + draw(st.sampled_from(WRONG_VALUES)), lines[i], count=1)
        elif op == "drop":
            del lines[i]
        elif op == "double":
            lines.insert(i, lines[i])
        elif op == "cut":
            text = text[: draw(st.integers(0, len(text)))]
            continue
        elif op == "bytes":
            lines.insert(i, draw(st.binary(max_size=12)).decode("latin-1"))
        elif op == "key":
            lines[i] = draw(st.sampled_from(["x_mm = 1\n", "[extra]\n", "[[link]]\n", "[[path]]\n", "kind = 1\n"]))
        text = "".join(lines)
    return text.encode("utf-8", "surrogateescape") if draw(st.booleans()) else text.encode("latin-1", "replace")


def _load(kind: str, data: bytes) -> None:
    path = _folder / f"{kind}-{next(_counter)}.toml"
    path.write_bytes(data)
    try:
        LOADERS[kind](str(path))
    except ScannerError as exc:
        assert str(exc).strip(), "an error without a message"
        assert "\n" not in str(exc).strip(), f"not one line: {exc}"
    finally:
        path.unlink(missing_ok=True)


FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow],
                derandomize=True)


@pytest.mark.parametrize("kind", ["scene", "robot", "probe"])
def test_mutated_files_load_or_give_one_error(kind):
    @FUZZ
    @given(mutated(kind))
    def check(data):
        _load(kind, data)

    check()


@pytest.mark.parametrize("kind", ["scene", "robot", "probe"])
def test_arbitrary_text_loads_or_gives_one_error(kind):
    @settings(max_examples=60, deadline=None, derandomize=True)
    @given(st.one_of(st.text(max_size=300), st.binary(max_size=300).map(lambda b: b.decode("latin-1"))))
    def check(text):
        _load(kind, text.encode("utf-8", "surrogatepass"))

    check()
