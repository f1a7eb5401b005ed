"""Packaging (issue 7): the zips made by scripts/package.sh install into a
clean Blender user configuration the way a user installs them (Preferences >
Add-ons > Install, or Get Extensions > Install from Disk on 4.2+), and the
installed add-on renders a shared scene headless. A package without a
loadable core still registers and says exactly why it cannot render."""

import os
import subprocess
import sys

import bpy
import pytest

from helpers import SCENES

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
IS_MODULE = not bpy.app.binary_path
HAS_EXTENSIONS = bpy.app.version >= (4, 2, 0)


@pytest.fixture(scope="module")
def packages(tmp_path_factory):
    dist = tmp_path_factory.mktemp("dist")
    env = dict(os.environ, DIST=str(dist))
    for no_core in ("0", "1"):
        subprocess.run([os.path.join(ROOT, "scripts", "package.sh")], env=dict(env, NO_CORE=no_core),
                       check=True, capture_output=True, timeout=900)
    zips = {p.name: str(p) for p in dist.iterdir()}
    pick = lambda kind, nocore: next(v for k, v in zips.items() if kind in k and k.endswith("-nocore.zip") == nocore)
    return {"addon": pick("-addon-", False), "extension": pick("-extension-", False),
            "addon_nocore": pick("-addon-", True), "extension_nocore": pick("-extension-", True)}


def clean_env(tmp_path):
    """Blender's user folders in a temporary directory: nothing installed, nothing enabled."""
    env = dict(os.environ)
    for var, sub in (("BLENDER_USER_CONFIG", "config"), ("BLENDER_USER_SCRIPTS", "scripts"),
                     ("BLENDER_USER_DATAFILES", "datafiles"), ("BLENDER_USER_EXTENSIONS", "extensions")):
        # Blender ignores these variables for folders that do not exist (and then reads
        # and writes the real user's preferences): create them first.
        (tmp_path / "user" / sub).mkdir(parents=True, exist_ok=True)
        env[var] = str(tmp_path / "user" / sub)
    env.pop("PYTHONPATH", None)
    return env


def run_in_blender(code, env, *blender_args):
    """Runs Python code in a fresh Blender (application or bpy module) with env."""
    if IS_MODULE:
        cmd = [sys.executable, "-c", "import bpy\n" + code]
    else:
        cmd = [bpy.app.binary_path, "-b", *blender_args, "--python-expr", code]
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600)
    print(proc.stdout[-4000:], proc.stderr[-4000:])
    return proc


INSTALL = """
import bpy, sys
kind, path = {kind!r}, {path!r}
if kind == "extension":
    bpy.ops.extensions.package_install_files(filepath=path, repo="user_default", enable_on_install=True)
    module = "bl_ext.user_default.tessera"
else:
    bpy.ops.preferences.addon_install(filepath=path)
    bpy.ops.preferences.addon_enable(module="tessera")
    module = "tessera"
import importlib
core = importlib.import_module(module + ".core")
print("TESSERA_MODULE", importlib.import_module(module).__file__)
print("TESSERA_LOAD_ERROR", core.load_error)
print("TESSERA_ENGINE", "TESSERA" in {{getattr(e, "bl_idname", None) for e in bpy.types.RenderEngine.__subclasses__()}})
bpy.ops.wm.save_userpref()
"""

RENDER = """
import bpy, sys, os
# The bpy module starts from factory settings and enables no add-on on import: read the
# saved preferences and enable what they list, as the Blender application does at start-up.
bpy.ops.wm.read_userpref()
import addon_utils
for m in [a.module for a in bpy.context.preferences.addons if "tessera" in a.module]:
    addon_utils.enable(m, default_set=True)
bpy.ops.wm.open_mainfile(filepath={scene!r})
s = bpy.context.scene
s.render.engine = "TESSERA"
s.render.resolution_x, s.render.resolution_y, s.render.resolution_percentage = 32, 24, 100
s.tessera.samples = 4
s.render.image_settings.file_format = "PNG"
s.render.filepath = {out!r}
try:
    bpy.ops.render.render(write_still=True)
except RuntimeError as e:
    print("TESSERA_RENDER_ERROR", e)
    sys.exit(1)
print("TESSERA_RENDERED", os.path.getsize({out!r}))
"""


def install(tmp_path, kind, path):
    env = clean_env(tmp_path)
    proc = run_in_blender(INSTALL.format(kind=kind, path=path), env)
    assert proc.returncode == 0
    assert "Writing userprefs: '" + str(tmp_path) in proc.stdout or IS_MODULE, "preferences not saved in the clean folder"
    assert f"TESSERA_MODULE {tmp_path}" in proc.stdout, "the add-on was not loaded from the clean user folders"
    assert "TESSERA_ENGINE True" in proc.stdout
    return env, proc.stdout


def render_headless(tmp_path, env):
    """Renders a shared scene in a new process that only has the saved preferences."""
    out = str(tmp_path / "render_0001.png")
    if IS_MODULE:
        return run_in_blender(RENDER.format(scene=os.path.join(SCENES, "cornell_mcguire.blend"), out=out), env), out
    # The farm way: the add-on enabled in the user's preferences, -E picks the engine.
    proc = subprocess.run([bpy.app.binary_path, "-b", os.path.join(SCENES, "cornell_mcguire.blend"),
                           "--python-expr", "import bpy; r = bpy.context.scene.render; r.resolution_x, "
                           "r.resolution_y, r.resolution_percentage = 32, 24, 100",
                           "-E", "TESSERA", "-o", str(tmp_path / "render_####"), "-F", "PNG", "-f", "1"],
                          env=env, capture_output=True, text=True, timeout=600)
    print(proc.stdout[-4000:], proc.stderr[-4000:])
    return proc, out


KINDS = ["addon"] + (["extension"] if HAS_EXTENSIONS else [])


@pytest.mark.parametrize("kind", KINDS)
def test_installed_package_renders_headless(tmp_path, packages, kind):
    env, out = install(tmp_path, kind, packages[kind])
    assert "TESSERA_LOAD_ERROR None" in out
    proc, image = render_headless(tmp_path, env)
    assert proc.returncode == 0
    assert "Tessera: 32x24" in proc.stdout, "the render did not go through Tessera"
    assert os.path.getsize(image) > 0


@pytest.mark.parametrize("kind", KINDS)
def test_package_without_core_registers_and_says_why(tmp_path, packages, kind):
    env, out = install(tmp_path, kind, packages[kind + "_nocore"])
    assert "TESSERA_LOAD_ERROR Tessera's native core could not be loaded into this Blender (Python 3." in out
    assert "_core" in out, "the reason names the missing module"
    proc, image = render_headless(tmp_path, env)
    assert proc.returncode != 0, "a render without the core must fail"
    assert "Tessera's native core could not be loaded" in proc.stdout + proc.stderr
    assert not os.path.exists(image)
