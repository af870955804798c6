"""The built zip in each supported Blender, installed with Blender's own installer.

For Blender 4.5 LTS (CPython 3.11, numpy 1.26) and 5.2 LTS (CPython 3.13, numpy 2.x),
and with SCANNER_BLENDERS=all also 5.0 and 5.1, the test command sets up a bare bpy (``python -m headless.bootstrap blender-env X.Y``:
bpy and what bpy itself needs, nothing of the project's, so the zip's own wheels are
what runs). In each, a subprocess with its own Blender user folder installs the zip,
checks that the extension really is enabled (the installer reports FINISHED even when
it refuses a package), builds the cell, renders the probe views, scans part of the
demo through the panel's operator and again with the raycast engine (the zip's Embree),
then disables and removes it. The cloud is checked
here against the exact sphere. A failure names the Blender release and the step.
"""

import json
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from headless.bootstrap import BLENDER_ENVS, LTS_RELEASES, ensure_blender_env

RELEASES = sorted(BLENDER_ENVS) if os.environ.get("SCANNER_BLENDERS") == "all" else list(LTS_RELEASES)

REPO = Path(__file__).resolve().parents[2]
PKG = "laser_scanner_sim"

# Runs inside the bare Blender. Each step is named before it starts, so that a failure
# (an exception, or a check that does not hold) reports where it happened.
SESSION = r"""
import json, sys, traceback
from pathlib import Path
import bpy, addon_utils
zip_path, scans = sys.argv[1], sys.argv[2]
module = "bl_ext.user_default.laser_scanner_sim"
out = {"blender": bpy.app.version_string, "python": "%d.%d" % sys.version_info[:2]}

def check(ok, what):
    if not ok:
        raise AssertionError(what)

try:
    out["step"] = "install"
    res = bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default", enable_on_install=True)
    out["install_result"] = str(res)
    check(module in bpy.context.preferences.addons, "the installer did not enable the extension")
    out["step"] = "bundled wheels"
    local = (Path(bpy.utils.user_resource("EXTENSIONS")) / ".local" / "lib" / ("python" + out["python"])
             / "site-packages")
    out["wheels"] = sorted(p.name for p in local.iterdir()) if local.is_dir() else []
    import trimesh, cv2, scipy, numpy
    out["trimesh_from_zip"] = Path(trimesh.__file__).is_relative_to(local)
    out["cv2_from_zip"] = Path(cv2.__file__).is_relative_to(local)
    out["numpy"] = numpy.__version__
    out["step"] = "URDF robot"
    import importlib, yourdfpy
    out["yourdfpy_from_zip"] = Path(yourdfpy.__file__).is_relative_to(local)
    ext = importlib.import_module(module)
    rigs = importlib.import_module(module + ".addon.core.config.rigs")
    gantry = rigs.load_robot(Path(ext.__file__).parent / "rigs" / "robots" / "urdf" / "gantry.urdf")
    out["urdf_prismatic"] = list(gantry.prismatic)
    # COLLADA meshes (most ROS robots' visual meshes) read through the zip's pycollada.
    import collada, tempfile
    out["collada_from_zip"] = Path(collada.__file__).is_relative_to(local)
    dae = Path(tempfile.mkdtemp()) / "box.dae"
    dae.write_bytes(trimesh.exchange.dae.export_collada(trimesh.creation.box((0.1, 0.2, 0.3))))
    out["dae_extents"] = sorted(trimesh.load(dae, force="mesh").extents.tolist())
    out["step"] = "a mesh part's distances signed (the zip's libigl)"
    import igl
    out["igl_from_zip"] = Path(igl.__file__).is_relative_to(local)
    metrics = importlib.import_module(module + ".addon.core.geometry.metrics")
    ball = trimesh.creation.icosphere(subdivisions=3, radius=10.0)
    _, signed = metrics.mesh_distances(numpy.array([[0.0, 0.0, 9.0], [0.0, 0.0, 12.0]]), ball)
    out["signed"] = None if signed is None else [float(v) for v in signed]
    out["step"] = "build cell"
    check(bpy.ops.scanner.build_cell() == {"FINISHED"}, "scanner.build_cell did not finish")
    def over_the_part():  # the probe 150 mm above the sphere's top: the line lies on the part
        bpy.context.scene.scanner.target_location = (0.0, 0.0, 210.0)
        check(bpy.ops.scanner.go() == {"FINISHED"}, "scanner.go did not finish")
    over_the_part()
    out["step"] = "render probe views"
    check(bpy.ops.scanner.render_views() == {"FINISHED"}, "scanner.render_views did not finish")
    def views():
        found = []
        for name in ("Probe camera 0", "Probe camera 1"):
            img = bpy.data.images[name]
            px = [0.0] * (img.size[0] * img.size[1] * 4)
            img.pixels.foreach_get(px)
            found.append({"size": list(img.size), "max": max(px[0::4])})
        return found
    out["views"] = views()
    out["step"] = "render probe views with Eevee's spot laser"
    bpy.context.scene.scanner.laser = "spot"
    check(bpy.ops.scanner.build_cell() == {"FINISHED"}, "scanner.build_cell (spot laser) did not finish")
    over_the_part()
    check(bpy.ops.scanner.render_views() == {"FINISHED"}, "scanner.render_views (Eevee) did not finish")
    out["eevee_views"] = views()
    bpy.context.scene.scanner.laser = "gobo"
    out["step"] = "an artist's prop on the turntable and its spin through a scan of the cell built here"
    s = bpy.context.scene.scanner
    def turntable():
        return next(o for o in bpy.data.collections["Scanner Cell"].all_objects
                    if o.get("scanner_cell_role") == "Turntable")
    table = turntable()
    prop = bpy.data.objects.new("Prop", None)
    bpy.context.scene.collection.objects.link(prop)
    prop.parent = table
    prop.location = (0.1, 0.0, 0.02)
    table.keyframe_insert("rotation_euler", index=2, frame=1)
    table.rotation_euler[2] = 6.283185
    table.keyframe_insert("rotation_euler", index=2, frame=120)
    spin = table.animation_data.action
    bpy.context.view_layer.update()
    where = prop.matrix_world.translation.copy()
    s.scan_config, s.scan_engine, s.output_dir = "CELL", "raycast", str(Path(scans).parent / "cell_scans")
    check(bpy.ops.scanner.scan(frames="0:3") == {"FINISHED"}, "scanner.scan of the cell built here did not finish")
    bpy.context.view_layer.update()
    check(prop.parent == turntable() and (prop.matrix_world.translation - where).length < 1e-6,
          "the prop parented to the turntable lost its place")
    check(turntable().animation_data is not None and turntable().animation_data.action == spin,
          "the turntable lost the artist's animation")
    turntable().animation_data_clear()
    bpy.data.objects.remove(prop)
    s.scan_engine = "CONFIG"
    out["step"] = "scan"
    s.scan_config = "demo"
    s.output_dir = scans
    check(bpy.ops.scanner.scan(frames="0:120:12") == {"FINISHED"}, "scanner.scan did not finish")
    out["cloud_object_points"] = len(bpy.data.objects["Scan cloud"].data.vertices)
    out["step"] = "raycast scan (the zip's embreex in Blender's Python)"
    api = importlib.import_module(module + ".addon")
    rc = api.Scanner.from_config("demo", engine="raycast", frames=slice(0, 120, 12))
    rc.run()
    rc_result = rc.result()
    out["raycast"] = {"points": len(rc_result.cloud.points), "rms_um": rc_result.report["error_um"]["rms_um"],
                      "device": rc_result.report["render_device"]}
    out["embreex_from_zip"] = Path(importlib.import_module("embreex").__file__).is_relative_to(local)
    out["step"] = "calibrate"
    calibrations = str(Path(scans).parent / "calibrations")
    check(bpy.ops.scanner.calibrate(config="demo", views=6, output_dir=calibrations) == {"FINISHED"},
          "scanner.calibrate did not finish")
    summary = json.loads(next(Path(calibrations).rglob("calibration.json")).read_text())
    out["calibration_px"] = [summary[f"camera{c}"]["reprojection_error_px"] for c in (0, 1)]
    out["calibration_field_um"] = summary["triangulation_error"]["all"]["rms_mm"] * 1e3
    out["step"] = "disable"
    bpy.ops.preferences.addon_disable(module=module)
    out["after_disable"] = {"scene_prop": hasattr(bpy.types.Scene, "scanner"),
                            "classes": [n for n in dir(bpy.types) if n.startswith("SCANNER_")],
                            "enabled": module in bpy.context.preferences.addons}
    out["step"] = "uninstall"
    repo_index = [r.module for r in bpy.context.preferences.extensions.repos].index("user_default")
    bpy.ops.extensions.package_uninstall(repo_index=repo_index, pkg_id="laser_scanner_sim")
    out["installed_after_uninstall"] = (Path(bpy.utils.user_resource("EXTENSIONS")) / "user_default"
                                        / "laser_scanner_sim").exists()
    out["step"] = "done"
except BaseException as exc:
    out["error"] = "".join(traceback.format_exception_only(exc)).strip()
print("RESULT " + json.dumps(out), flush=True)
"""


@pytest.fixture(scope="module")
def linux_zip(tmp_path_factory):
    out = tmp_path_factory.mktemp("dist")
    res = subprocess.run([sys.executable, "-m", "headless", "build-extension", "--platforms", "linux-x64",
                          "--out", str(out)], cwd=REPO, capture_output=True, text=True)
    assert res.returncode == 0, res.stdout + res.stderr
    (zip_path,) = out.glob("*.zip")
    return zip_path


def test_zip_ships_the_addon_its_rigs_and_linux_wheels_for_both_pythons(linux_zip):
    names = set(zipfile.ZipFile(linux_zip).namelist())
    for needed in ("blender_manifest.toml", "__init__.py", "addon/core/kinematics/robot.py", "addon/scanner.py", "addon/ui/ops.py",
                   "addon/scene/compat.py", "rigs/robots/adept_viper_s650.toml", "rigs/scenes/demo.toml"):
        assert needed in names
    wheels = [n for n in names if n.startswith("wheels/")]
    assert wheels and all(("linux" in w or "-any" in w) for w in wheels)
    for package in ("scipy", "embreex", "lxml"):
        tags = {w.split("-")[2] for w in wheels if w.startswith(f"wheels/{package}-")}
        assert tags == {"cp311", "cp313"}, (package, tags)
    tags = {tuple(w.split("-")[2:4]) for w in wheels if w.startswith("wheels/libigl-")}
    assert tags == {("cp311", "cp311"), ("cp312", "abi3")}, tags  # 4.5 and 5.0; 5.1 and 5.2
    assert not [n for n in names if n.startswith(("tests/", "headless/", ".venv", ".ci/", ".git"))]
    assert not [n for n in names if "__pycache__" in n or n.endswith(".pyc")]


@pytest.mark.parametrize("release", RELEASES)
def test_install_enable_scan_disable_uninstall(release, linux_zip, tmp_path):
    python = ensure_blender_env(release)  # bare bpy of that release, set up once and cached
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "VIRTUAL_ENV"))}
    env["BLENDER_USER_RESOURCES"] = str(tmp_path / "blender-user")
    scans = tmp_path / "scans"
    res = subprocess.run([str(python), "-c", SESSION, str(linux_zip), str(scans)], env=env, capture_output=True,
                         text=True, cwd=tmp_path, timeout=900)
    lines = [ln for ln in res.stdout.splitlines() if ln.startswith("RESULT ")]
    assert lines, f"Blender {release}: no result (exit {res.returncode}):\n{res.stdout[-3000:]}{res.stderr[-3000:]}"
    out = json.loads(lines[0][len("RESULT "):])
    where = f"Blender {out.get('blender', release)}, step '{out.get('step')}'"
    assert "error" not in out, f"{where}: {out.get('error')}\n{res.stderr[-3000:]}"
    assert out["blender"].startswith(release) and out["python"] == "%d.%d" % BLENDER_ENVS[release]
    assert {"trimesh", "cv2", "rtree", "scipy", "embreex"} <= set(out["wheels"]), where
    assert out["trimesh_from_zip"] and out["cv2_from_zip"], f"{where}: the zip's wheels are not what runs"
    assert out["yourdfpy_from_zip"] and out["urdf_prismatic"] == [True] * 3 + [False] * 3, where
    assert out["collada_from_zip"] and np.allclose(out["dae_extents"], [0.1, 0.2, 0.3]), where
    # The signed distances of the metrics (a mesh part's bias), through the zip's libigl in each Blender
    # (none shipped: unsigned, and 40 times slower)
    assert out["igl_from_zip"] and out["signed"] is not None, f"{where}: {out.get('signed')}"
    assert -1.0 < out["signed"][0] < -0.9 and 1.99 < out["signed"][1] < 2.01, f"{where}: {out['signed']}"
    for view in out["views"]:  # the laser line, far above the ambient 0.08 (which passed alone before)
        assert view["size"] == [160, 160] and view["max"] > 0.3, f"{where}: probe view {view}"
    # Eevee (4.5's Eevee Next and 5.x's) renders the spots' line as bright as Cycles the gobo's.
    for view, eevee in zip(out["views"], out["eevee_views"]):
        assert eevee["size"] == [160, 160] and 0.8 < eevee["max"] / view["max"] < 1.25, f"{where}: {eevee} {view}"
    assert out["cloud_object_points"] > 500, where
    # The raycast engine in Blender's own Python, from the zip's embreex: a cloud as good as Cycles'.
    assert out["embreex_from_zip"] and out["raycast"]["device"].startswith("CPU (Embree"), f"{where}: {out['raycast']}"
    assert out["raycast"]["points"] > 500 and out["raycast"]["rms_um"] < 25, f"{where}: {out['raycast']}"
    # ChArUco boards rendered and found inside each Blender: corners to a fraction of a pixel
    assert max(out["calibration_px"]) < 0.3 and out["calibration_field_um"] < 500, f"{where}: {out}"
    assert out["after_disable"] == {"scene_prop": False, "classes": [], "enabled": False}, where
    assert out["installed_after_uninstall"] is False, where
    # The cloud against the demo's exact part: a sphere of 30 mm radius standing on the table.
    (ply,) = scans.rglob("cloud.ply")
    import trimesh

    points = np.asarray(trimesh.load(ply).vertices)
    on_sphere = points[points[:, 2] > 1.0]
    error_um = (np.linalg.norm(on_sphere - [0.0, 0.0, 30.0], axis=1) - 30.0) * 1000
    assert len(on_sphere) > 300, where
    assert np.sqrt(np.mean(error_um ** 2)) < 25 and np.abs(error_um).max() < 200, \
        f"{where}: RMS {np.sqrt(np.mean(error_um ** 2)):.1f} um, max {np.abs(error_um).max():.1f} um"
    on_table = points[points[:, 2] <= 1.0]
    assert len(on_table) > 300 and np.abs(on_table[:, 2]).max() < 0.1, where
    print(f"\nBlender {out['blender']} (CPython {out['python']}, numpy {out['numpy']}): enabled, cell built, "
          f"probe views {out['views'][0]['size'][0]}x{out['views'][0]['size'][1]} (line peak "
          f"{out['views'][0]['max']:.3f} Cycles gobo, {out['eevee_views'][0]['max']:.3f} Eevee spots), scan of 10 demo frames "
          f"{len(points)} points, sphere RMS {np.sqrt(np.mean(error_um ** 2)):.1f} um "
          f"(max {np.abs(error_um).max():.1f} um), table |z| max {np.abs(on_table[:, 2]).max() * 1000:.1f} um; "
          f"raycast scan {out['raycast']['points']} points, RMS {out['raycast']['rms_um']:.1f} um; "
          f"calibration from 6 poses {out['calibration_px'][0]:.3f}/{out['calibration_px'][1]:.3f} px, "
          f"{out['calibration_field_um']:.0f} um RMS on the laser plane")
