"""Renders a warp-cloth USD result in Blender (the ``bpy`` module): run by ``warp_cloth.preview`` as
``python preview_blender.py JOB.json`` in a process of its own, since Blender carries its own USD libraries.

The job (JSON) names the USD file, the pictures to make and how; this script imports the stage as Blender's
USD importer does for a user (subdivision included, so a ``catmullClark`` cloth renders smooth), gives each
prim a material of its display colour by role (cloth, collider, ground), frames a camera on the cloths and
colliders, lights the scene and renders the still with Cycles on the CPU and the animation with Blender's
viewport renderer (Workbench: a quarter of a second a picture on two cores, where Cycles takes two), or
Cycles where no OpenGL context can be made. It prints ``STILL`` when the still is written, ``FRAME n`` after
each picture of the animation (``RESTART`` where it starts again with Cycles), for the caller's progress bar.
"""

import json
import math
import sys

import bpy
from mathutils import Vector

FRONT = Vector((0.0, -1.0, 0.0))  # Blender's front (USD's +Z, after the importer's turn to Z up)
ELEVATION = (math.radians(20), math.radians(50))  # the camera's height above the horizon, at least / at most
AZIMUTH_OFFSET = math.radians(30)  # a three-quarter view rather than square on
LENS_MM, SENSOR_MM = 50.0, 36.0
MARGIN = 1.1  # the framed bounds, this much larger, fit the view
FRAMING_SAMPLES = 24  # frames whose bounds the animation's camera is framed on
SMOOTH_ANGLE = math.radians(30)  # a collider's faces meeting at more than this are shaded with a sharp edge


def main(job_path: str) -> None:
    job = json.loads(open(job_path).read())
    meshes, role = import_result(job)
    scene = bpy.context.scene
    framed = [o for o in meshes if role[o.name] != "ground"] or meshes
    cloths = [o for o in meshes if role[o.name] == "cloth"]
    scene.frame_set(job["still_frame"])
    view = view_direction(cloths)
    light(scene, view)
    render = scene.render
    render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.max_bounces = 4
    render.resolution_x, render.resolution_y = job["resolution"]
    render.resolution_percentage = 100
    render.use_persistent_data = True  # the scene's BVH and shaders kept from one picture to the next

    place_camera(scene, framed, [job["still_frame"]], view)  # the still framed on its frame
    scene.frame_set(job["still_frame"])
    scene.cycles.samples = job["samples"]
    scene.cycles.use_denoising = True  # about 1.5 s a picture on two cores: the still's only
    render.image_settings.file_format = "PNG"
    render.filepath = job["still"]
    bpy.ops.render.render(write_still=True)
    print("STILL", flush=True)

    animation = job.get("animation")
    if animation is None:
        return
    start, end, step = job["frames"]
    span = sorted({round(start + (end - start) * k / (FRAMING_SAMPLES - 1)) for k in range(FRAMING_SAMPLES)})
    place_camera(scene, framed, span, view)  # the animation framed on the whole run: a camera that holds still
    scene.frame_start, scene.frame_end, scene.frame_step = start, end, step
    scene.cycles.samples = job["animation_samples"]
    scene.cycles.use_denoising = False
    render.engine = "BLENDER_WORKBENCH"  # Blender's viewport renderer: a picture in a quarter second here
    shading = scene.display.shading
    shading.light, shading.color_type, shading.show_shadows = "STUDIO", "MATERIAL", True
    render.resolution_x, render.resolution_y = job["animation_resolution"]
    render.fps = max(1, round(job["fps"] / step))  # the animation plays at the run's speed
    bpy.app.handlers.render_post.append(lambda s, *_: print(f"FRAME {s.frame_current}", flush=True))
    if animation["format"] == "mp4":
        render.image_settings.media_type = "VIDEO"
        render.image_settings.file_format = "FFMPEG"
        render.ffmpeg.format, render.ffmpeg.codec = "MPEG4", "H264"
        render.ffmpeg.constant_rate_factor = "HIGH"
        render.use_file_extension = False
        render.filepath = animation["path"]
    else:  # pictures, which the caller makes into a GIF
        render.filepath = animation["path"] + "/frame_####"
    try:
        bpy.ops.render.render(animation=True)
    except RuntimeError:  # no OpenGL context to be had (no EGL): Cycles, as the still
        print("RESTART", flush=True)
        render.engine = "CYCLES"
        bpy.ops.render.render(animation=True)


def import_result(job: dict) -> tuple[list, dict]:
    """The job's USD in an empty scene, each mesh given its material and shading by role: its meshes, and
    each one's role by name."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.usd_import(filepath=job["usd"], import_subdivision=True, set_frame_range=True, import_materials=False)
    meshes = [o for o in bpy.context.scene.objects if o.type == "MESH"]
    if not meshes:
        raise SystemExit(f"preview: no mesh in {job['usd']}")
    role = {}
    for obj in meshes:
        role[obj.name], color = job["prims"].get(obj.name, ("cloth", [0.7, 0.7, 0.7]))
        obj.data.materials.clear()
        obj.data.materials.append(material(obj.name, role[obj.name], color))
        shade(obj.data, role[obj.name])
    return meshes, role


def shade(mesh, role: str) -> None:
    """A cloth smooth (a surface its particles sample); a collider smooth across its edges flatter than
    ``SMOOTH_ANGLE`` and sharp across the others, as a DCC tool's auto smooth (a box's faces flat, a sphere
    or a cylinder's side round, its rim sharp); the ground flat."""
    if role == "ground":
        return
    mesh.shade_smooth()
    if role != "cloth":
        mesh.set_sharp_from_angle(angle=SMOOTH_ANGLE)


def material(name: str, role: str, color: list) -> "bpy.types.Material":
    mat = bpy.data.materials.new(f"{name}_{role}")
    mat.use_nodes = True
    shader = mat.node_tree.nodes["Principled BSDF"]
    shader.inputs["Base Color"].default_value = (*color, 1.0)
    mat.diffuse_color = (*color, 1.0)  # what the viewport renderer shows
    shader.inputs["Roughness"].default_value = {"cloth": 0.8, "collider": 0.35, "ground": 0.9}.get(role, 0.6)
    if role == "cloth":
        shader.inputs["Sheen Weight"].default_value = 0.3
    return mat


def view_direction(cloths: list) -> Vector:
    """From the target to the camera: facing the cloths' mean surface at the current frame (the side
    nearer the front), turned a little for a three-quarter view, between ``ELEVATION``'s bounds above the
    horizon (a cloth lying flat is seen from the front, from above)."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    normal = Vector((0.0, 0.0, 0.0))
    for obj in cloths:
        evaluated = obj.evaluated_get(depsgraph)
        mesh = evaluated.to_mesh()
        turn = evaluated.matrix_world.to_3x3()
        for polygon in mesh.polygons:
            normal += (turn @ polygon.normal) * polygon.area
        evaluated.to_mesh_clear()
    if normal.dot(FRONT + Vector((0.0, 0.0, 0.3))) < 0:
        normal = -normal
    across = Vector((normal.x, normal.y, 0.0))
    azimuth = math.atan2(across.x, -across.y) if across.length > 0.2 * normal.length else 0.0
    azimuth += AZIMUTH_OFFSET
    elevation = math.atan2(normal.z, across.length) if normal.length > 0 else ELEVATION[1]
    elevation = min(max(elevation, ELEVATION[0]), ELEVATION[1])
    return Vector((math.sin(azimuth) * math.cos(elevation), -math.cos(azimuth) * math.cos(elevation),
                   math.sin(elevation)))


def place_camera(scene, framed: list, frames: list, view: Vector) -> None:
    """The scene's camera, made to see every framed object at each of ``frames``, looking back along
    ``view``."""
    low, high = Vector((math.inf,) * 3), Vector((-math.inf,) * 3)
    for frame in frames:
        scene.frame_set(frame)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        for obj in framed:
            evaluated = obj.evaluated_get(depsgraph)
            for corner in evaluated.bound_box:
                p = evaluated.matrix_world @ Vector(corner)
                low, high = Vector(map(min, low, p)), Vector(map(max, high, p))
    center = (low + high) / 2
    aspect = scene.render.resolution_x / scene.render.resolution_y
    tan_x = SENSOR_MM / 2 / LENS_MM
    tan_y = tan_x / aspect
    # The camera's axes: right, up, and back along VIEW; every corner of the bounds within the view.
    back = view
    right = Vector((0.0, 0.0, 1.0)).cross(back).normalized()
    up = back.cross(right)
    distance = 0.0
    for corner in ((x, y, z) for x in (low.x, high.x) for y in (low.y, high.y) for z in (low.z, high.z)):
        offset = Vector(corner) - center
        along = offset.dot(back)
        distance = max(distance, along + MARGIN * abs(offset.dot(right)) / tan_x,
                       along + MARGIN * abs(offset.dot(up)) / tan_y)
    distance = max(distance, 1e-3)
    if scene.camera is None:
        data = bpy.data.cameras.new("preview")
        data.lens, data.sensor_width, data.sensor_fit = LENS_MM, SENSOR_MM, "HORIZONTAL"
        scene.camera = bpy.data.objects.new("preview", data)
        scene.collection.objects.link(scene.camera)
    camera = scene.camera
    camera.data.clip_start, camera.data.clip_end = distance / 1000, distance * 10
    camera.location = center + view * distance
    camera.rotation_euler = (-view).to_track_quat("-Z", "Y").to_euler()


def light(scene, view: Vector) -> None:
    """A sun from above the camera's left shoulder, and a pale sky."""
    right = Vector((0.0, 0.0, 1.0)).cross(view).normalized()
    toward_sun = (view - 0.6 * right + Vector((0.0, 0.0, 0.8))).normalized()
    sun = bpy.data.objects.new("sun", bpy.data.lights.new("sun", "SUN"))
    sun.data.energy = 4.0
    sun.data.angle = math.radians(10)
    sun.rotation_euler = (-toward_sun).to_track_quat("-Z", "Y").to_euler()
    scene.collection.objects.link(sun)
    world = bpy.data.worlds.new("preview")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.75, 0.8, 0.88, 1.0)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.45
    world.color = (0.75, 0.8, 0.88)  # the viewport renderer's background
    scene.world = world


if __name__ == "__main__":
    main(sys.argv[-1])
