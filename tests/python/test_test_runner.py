"""scripts/test.sh runs the Blender suite once per available Blender: Debian's
`blender` and every bpy venv scripts/setup_bpy.sh made under ~/.cache/tessera,
or exactly TESSERA_BLENDERS, and says which versions ran. Run here on a copy
of the script with stand-ins for set-up, CTest and the Blenders (seconds, no
rendering)."""

import os
import shutil
import stat
import subprocess

import pytest

ROOT = os.path.join(os.path.dirname(__file__), "..", "..")


def executable(path, text):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w") as f:
        f.write("#!/bin/sh\n" + text)
    os.chmod(path, os.stat(path).st_mode | stat.S_IXUSR)


@pytest.fixture
def runner(tmp_path):
    """A checkout with the real scripts/test.sh and a stand-in scripts/setup.sh,
    a PATH with stand-in ctest and blender (3.4.1), and an empty HOME."""
    repo, home, bin_dir = tmp_path / "repo", tmp_path / "home", tmp_path / "bin"
    (repo / "tests" / "python").mkdir(parents=True)
    (repo / "tests" / "python" / "test_nothing.py").write_text("def test_nothing():\n    pass\n")
    (repo / "scripts").mkdir()
    shutil.copy(os.path.join(ROOT, "scripts", "test.sh"), repo / "scripts" / "test.sh")
    executable(str(repo / "scripts" / "setup.sh"), "exit 0\n")
    executable(str(bin_dir / "ctest"), "exit 0\n")
    executable(str(bin_dir / "blender"),
               'if [ "$1" = --version ]; then echo "Blender 3.4.1"; fi\necho "blender $*" >> "$HOME/calls"\n')
    home.mkdir()

    def run(blenders=None):
        env = dict(os.environ, HOME=str(home), PATH=f"{bin_dir}:/usr/bin:/bin")
        env.pop("TESSERA_BLENDERS", None)
        if blenders is not None:
            env["TESSERA_BLENDERS"] = blenders
        return subprocess.run(["bash", str(repo / "scripts" / "test.sh")], env=env, capture_output=True,
                              text=True, timeout=120)
    return run, home


def bpy_venv(home, version, works=True):
    python = str(home / ".cache" / "tessera" / f"bpy-{version}.x" / "bin" / "python")
    executable(python, (f'if [ "$1" = -c ]; then echo "{version}.1"; exit 0; fi\n' if works else
                        'if [ "$1" = -c ]; then exit 1; fi\n') + f'echo "bpy {version} $*" >> "$HOME/calls"\n')
    return python


def summary(result):
    lines = [line for line in result.stdout.splitlines() if "Blender suites ran on" in line]
    assert lines, result.stdout + result.stderr
    return lines[-1]


def test_fresh_machine_runs_debians_blender_only(runner):
    run, home = runner
    result = run()
    assert result.returncode == 0, result.stdout + result.stderr
    assert summary(result).endswith("ran on: Blender 3.4.1 (ok)")


def test_every_bpy_venv_of_setup_bpy_is_run_by_default(runner):
    # Regression: without TESSERA_BLENDERS only Debian's blender ran.
    run, home = runner
    bpy_venv(home, "4.5")
    bpy_venv(home, "5.0")
    result = run()
    assert result.returncode == 0, result.stdout + result.stderr
    assert summary(result).endswith("ran on: Blender 3.4.1 (ok), bpy 4.5.1 (ok), bpy 5.0.1 (ok)")
    calls = (home / "calls").read_text()
    assert "bpy 4.5 tests/blender/run.py -q" in calls and "bpy 5.0 tests/blender/run.py -q" in calls


def test_tessera_blenders_overrides(runner):
    run, home = runner
    bpy_venv(home, "4.5")
    five = bpy_venv(home, "5.0")
    result = run(blenders=five)
    assert summary(result).endswith("ran on: bpy 5.0.1 (ok)")


def test_a_broken_venv_fails_and_says_what_to_do(runner):
    run, home = runner
    bpy_venv(home, "4.5", works=False)
    result = run()
    assert result.returncode == 1
    assert "does not import bpy; remake the venv with scripts/setup_bpy.sh" in result.stdout
    assert "Blender 3.4.1 (ok)" in summary(result) and "(FAILED: no bpy)" in summary(result)
