"""The camera, framed exactly as Blender frames it: Blender's own view_frame
(sensor fit, shift, render size and pixel aspect) gives the rectangle the
core maps the image onto."""

import numpy as np


def export_camera(depsgraph, width, height, report=None):
    """Returns the keyword arguments of Scene.set_camera, or None without a camera."""
    scene = depsgraph.scene
    if scene.camera is None:
        return None
    cam_obj = scene.camera.evaluated_get(depsgraph)
    # Camera scale does not change the view (Cycles removes it too).
    matrix = np.array(cam_obj.matrix_world.normalized(), dtype=np.float32)
    if cam_obj.type != 'CAMERA':
        # Any object can be the scene camera: Blender then looks down its -Z
        # with a 50 mm lens on a 36 mm sensor.
        half = 0.5 * 36.0 / 50.0
        aspect = width / height
        hx, hy = (half, half / aspect) if aspect >= 1.0 else (half * aspect, half)
        return dict(type="PERSP", matrix=matrix, left=-hx, right=hx, bottom=-hy, top=hy,
                    clip_start=0.1, clip_end=1000.0, width=width, height=height)
    cam = cam_obj.data
    frame = cam.view_frame(scene=scene)
    if cam.type == 'ORTHO':
        xs = [v.x for v in frame]
        ys = [v.y for v in frame]
        kind = "ORTHO"
    else:
        if cam.type == 'PANO' and report is not None:
            report.warn(cam.name, f"Camera '{cam.name}' is panoramic, which Tessera does not render yet; "
                                  f"it is rendered as a perspective camera.")
        xs = [v.x / -v.z for v in frame]
        ys = [v.y / -v.z for v in frame]
        kind = "PERSP"
    return dict(type=kind, matrix=matrix,
                left=min(xs), right=max(xs), bottom=min(ys), top=max(ys),
                clip_start=cam.clip_start, clip_end=cam.clip_end, width=width, height=height)
