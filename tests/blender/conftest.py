import bpy
import pytest


@pytest.fixture(scope="session", autouse=True)
def tessera_registered():
    import tessera
    if not hasattr(bpy.types.Scene, "tessera"):
        tessera.register()
    yield
