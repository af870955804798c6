"""The core is grouped by stage and each stage imports only from stages below it.

Stages, bottom to top: the base modules at addon/core's root (errors, tolerances,
files, exr), kinematics, optics, geometry, safety, config, scan. The imports are read from
the source (ast), so a violation is caught even where no test runs that line.
"""

import ast
from pathlib import Path

CORE = Path(__file__).resolve().parents[2] / "addon" / "core"
STAGES = ["kinematics", "optics", "geometry", "safety", "config", "scan", "calibration"]


def stage_of(parts: list[str]) -> int:
    """-1 for the base modules at the core's root, else the stage's index."""
    return STAGES.index(parts[0]) if parts and parts[0] in STAGES else -1


def imported_core_modules(path: Path):
    """Core-relative module paths (as lists) that ``path`` imports."""
    rel = path.relative_to(CORE).with_suffix("").parts
    package = list(rel[:-1]) if rel[-1] != "__init__" else list(rel[:-1])
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level:
            base = package[: len(package) - (node.level - 1)] if node.level > 1 else package
            if node.level - 1 > len(package):
                continue  # above the core (addon/...): forbidden, reported by the caller
            target = base + (node.module.split(".") if node.module else [])
            if node.module is None:
                for alias in node.names:
                    yield node.lineno, target + [alias.name]
            else:
                yield node.lineno, target


def test_every_stage_is_a_package_with_a_curated_all():
    for stage in STAGES:
        init = CORE / stage / "__init__.py"
        assert init.is_file(), stage
        tree = ast.parse(init.read_text())
        names = [t.id for node in tree.body if isinstance(node, ast.Assign) for t in node.targets
                 if isinstance(t, ast.Name)]
        assert "__all__" in names, f"addon/core/{stage}/__init__.py has no __all__"


def test_imports_only_go_down():
    bad = []
    for path in CORE.rglob("*.py"):
        rel = path.relative_to(CORE).parts
        own = stage_of(list(rel)) if len(rel) > 1 else -1
        text = path.read_text()
        tree = ast.parse(text)
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.level:
                depth = len(rel) - 1  # packages between the core and this file
                if node.level - 1 > depth:
                    bad.append(f"{path.relative_to(CORE)}:{node.lineno} imports above addon.core")
        for lineno, target in imported_core_modules(path):
            if stage_of(target) > own:
                bad.append(f"{path.relative_to(CORE)}:{lineno} ({STAGES[own] if own >= 0 else 'base'}) imports "
                           f"{'.'.join(target)} ({STAGES[stage_of(target)]})")
    assert not bad, "\n".join(bad)
