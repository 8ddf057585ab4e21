"""Render a run's surface meshes (frame_NNNNN_<object>.ply) with Blender, headless.

    blender -b -P scripts/render.py -- DIR FRAME [FRAME ...] [-o OUT_PATTERN]
            [--samples N] [--size W H] [--camera X Y Z] [--look-at X Y Z] [--floor Y]
            [--engine CYCLES|BLENDER_WORKBENCH]

Writes OUT_PATTERN with {frame} replaced by each frame number (default DIR/render/frame_{frame:05d}.png):
every object's mesh of that frame, each in its own colour, smooth shaded, on a grey floor plane,
lit by a sun and a sky, seen from the camera. Cycles on the CPU (the default) needs no GPU
and no display. Run the engine with `--format mesh` (or `mpm surface DIR`) first.
"""
import argparse
import glob
import math
import os
import re
import sys

import bpy
from mathutils import Vector

PALETTE = [(0.85, 0.25, 0.2), (0.2, 0.45, 0.85), (0.95, 0.7, 0.15), (0.3, 0.7, 0.35),
           (0.6, 0.35, 0.75), (0.9, 0.5, 0.6)]


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="blender -b -P scripts/render.py --")
    p.add_argument("dir")
    p.add_argument("frames", type=int, nargs="+")
    p.add_argument("-o", "--out", default=None)
    p.add_argument("--samples", type=int, default=32)
    p.add_argument("--size", type=int, nargs=2, default=[960, 540])
    p.add_argument("--camera", type=float, nargs=3, default=[0.95, 0.5, 1.55])
    p.add_argument("--look-at", type=float, nargs=3, default=[0.55, 0.2, 0.5])
    p.add_argument("--floor", type=float, default=0.05, help="floor height (y, engine units)")
    p.add_argument("--engine", default="CYCLES", choices=["CYCLES", "BLENDER_WORKBENCH"])
    return p.parse_args(argv)


def engine_to_blender(v):
    """The engine's y-up coordinates to Blender's z-up: (x, y, z) -> (x, -z, y)."""
    return Vector((v[0], -v[2], v[1]))


def material(name, colour):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    bsdf = m.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*colour, 1)
    bsdf.inputs["Roughness"].default_value = 0.45
    m.diffuse_color = (*colour, 1)  # Workbench
    return m


def clear_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)


def setup(args):
    scene = bpy.context.scene
    scene.render.engine = args.engine
    scene.render.resolution_x, scene.render.resolution_y = args.size
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "PNG"
    if args.engine == "CYCLES":
        scene.cycles.device = "CPU"
        scene.cycles.samples = args.samples
        scene.cycles.use_denoising = False
    else:
        scene.display.shading.light = "STUDIO"
        scene.display.shading.color_type = "MATERIAL"
        scene.display.shading.show_shadows = True
    world = bpy.data.worlds.new("sky")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.75, 0.82, 0.92, 1)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.6
    scene.world = world

    # Floor: a large plane at the floor height (engine y is Blender z).
    bpy.ops.mesh.primitive_plane_add(size=20, location=(0.5, -0.5, args.floor))
    bpy.context.object.data.materials.append(material("floor", (0.35, 0.36, 0.38)))

    bpy.ops.object.light_add(type="SUN", rotation=(math.radians(40), math.radians(15),
                                                    math.radians(30)))
    bpy.context.object.data.energy = 2.5
    bpy.context.object.data.angle = math.radians(8)

    cam_pos = engine_to_blender(args.camera)
    target = engine_to_blender(args.look_at)
    bpy.ops.object.camera_add(location=cam_pos)
    cam = bpy.context.object
    cam.rotation_euler = (target - cam_pos).to_track_quat("-Z", "Y").to_euler()
    cam.data.lens = 40
    scene.camera = cam


def import_ply(path):
    before = set(bpy.data.objects)
    bpy.ops.import_mesh.ply(filepath=path)  # Blender 3.4's PLY importer
    new = [o for o in bpy.data.objects if o not in before]
    for o in new:
        # The engine is y-up: turn the mesh so its y becomes Blender's z.
        o.rotation_euler = (math.radians(90), 0, 0)
        for poly in o.data.polygons:
            poly.use_smooth = True
    return new


def main():
    args = parse_args()
    out = args.out or os.path.join(args.dir, "render", "frame_{frame:05d}.png")
    names = {}
    for frame in args.frames:
        clear_scene()
        setup(args)
        files = sorted(glob.glob(os.path.join(args.dir, "frame_%05d_*.ply" % frame)))
        if not files:
            sys.exit("render.py: no frame_%05d_*.ply in %s: run with --format mesh or "
                     "'mpm surface %s' first" % (frame, args.dir, args.dir))
        for f in files:
            obj_name = re.sub(r"^frame_\d+_(.*)\.ply$", r"\1", os.path.basename(f))
            colour = PALETTE[names.setdefault(obj_name, len(names)) % len(PALETTE)]
            for o in import_ply(f):
                o.data.materials.append(material(obj_name, colour))
        path = out.format(frame=frame)
        os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
        bpy.context.scene.render.filepath = os.path.abspath(path)
        bpy.ops.render.render(write_still=True)
        print("render.py: wrote", path)


main()
