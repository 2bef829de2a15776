"""The calib package as a whole: its public names, and which of its modules may import which."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

import calib

CALIB = Path(calib.__file__).resolve().parent


def _imports(path: Path) -> list[tuple[str, bool]]:
    """(module imported, inside a function?) for every import statement of a file."""
    out = []

    def visit(node: ast.AST, in_function: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.Import):
                out.extend((a.name, in_function) for a in child.names)
            elif isinstance(child, ast.ImportFrom):
                base = child.module or ""
                out.append((base, in_function))
                out.extend((f"{base}.{a.name}", in_function) for a in child.names)
            visit(child, in_function or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)))

    visit(ast.parse(path.read_text()), False)
    return out


MODULES = sorted(CALIB.rglob("*.py"))


def test_public_names():
    assert set(calib.__all__) == {
        "CalibrationError", "CalibrationReport", "CharucoBoard", "CheckerBoard", "RectificationWarning", "RectifiedRig",
        "StereoRig", "calibrate_stereo", "depth_from_disparity", "detect_board", "disparity_from_depth", "load_rig",
        "points_from_disparity", "points_from_pixels", "read_kitti_calib", "read_middlebury_calib", "read_oakd_calib",
        "vertical_offset",
    }
    assert all(hasattr(calib, name) for name in calib.__all__)


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(CALIB)))
def test_no_import_inside_a_function(path):
    lazy = [name for name, in_function in _imports(path) if in_function]
    assert set(lazy) <= {"tqdm", "tqdm.tqdm"}, f"{path.name} imports {lazy} inside a function"


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(CALIB)))
def test_leaf_package(path):
    names = [name for name, _ in _imports(path)]
    assert not [n for n in names if n.split(".")[0] in ("stereo_classic", "detectors", "benchmarks")]


@pytest.mark.parametrize("path", sorted((CALIB / "formats").glob("*.py")) + [CALIB / "rectified.py"],
                         ids=lambda p: str(p.relative_to(CALIB)))
def test_formats_and_rectified_do_not_import_the_rig(path):
    names = {name for name, _ in _imports(path)}
    forbidden = {"calib.rig", "calib.load", "calib.StereoRig"}
    if path.parent.name == "formats":
        forbidden |= {"calib.rectified", "calib.RectifiedRig", "calib.calibrate", "calib.synthetic"}
    assert not names & forbidden
    assert not {n for n in names if n == "calib"}  # never the package itself (it imports everything)


@pytest.mark.parametrize("module", ["calib.formats", "calib.formats.opencv", "calib.rectified", "calib.rig", "calib.load"])
def test_each_module_imports_first_in_a_fresh_interpreter(module):
    code = f"import {module}, sys; print(sorted(m for m in sys.modules if m.startswith('calib')))"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=CALIB.parent, timeout=120)
    assert done.returncode == 0, done.stderr
