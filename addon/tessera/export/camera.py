"""The camera, framed exactly as Blender frames it: Blender's own view_frame
(sensor fit, shift, render size and pixel aspect) gives the rectangle the
core maps the image onto; depth of field as Cycles converts it (thin lens of
radius focal length / (2 f-stop), focus distance along the view axis)."""

import numpy as np


def export_camera(depsgraph, width, height, report=None, camera_override=None):
    """Returns the keyword arguments of Scene.set_camera, or None without a
    camera. camera_override (RenderEngine.camera_override: a sequencer scene
    strip's camera, for one) replaces the scene's camera, as in Cycles' sync."""
    scene = depsgraph.scene
    camera_object = camera_override or scene.camera
    if camera_object is None:
        return None
    cam_obj = camera_object.evaluated_get(depsgraph)
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
                clip_start=cam.clip_start, clip_end=cam.clip_end, width=width, height=height,
                **depth_of_field(cam, cam_obj, depsgraph))


def depth_of_field(cam, cam_obj, depsgraph):
    """Scene.set_camera's lens arguments, as Cycles' blender_camera_from_object:
    aperture radius = focal length (mm, to metres) / (2 f-stop), or 1 / (2
    f-stop) for an orthographic camera; the focus object's distance along the
    camera's view axis, else the focus distance."""
    dof = cam.dof
    if not dof.use_dof:
        return dict(aperture_radius=0.0)
    fstop = max(dof.aperture_fstop, 1e-5)
    radius = 1.0 / (2.0 * fstop) if cam.type == 'ORTHO' else cam.lens * 1e-3 / (2.0 * fstop)
    focus = dof.focus_distance
    if dof.focus_object is not None:
        target = dof.focus_object.evaluated_get(depsgraph).matrix_world.translation
        m = cam_obj.matrix_world.normalized()
        view = m.col[2].xyz.normalized()
        focus = abs(view.dot(m.translation - target))
    return dict(aperture_radius=radius, focus_distance=focus, blades=dof.aperture_blades,
                blades_rotation=dof.aperture_rotation, aperture_ratio=dof.aperture_ratio)
