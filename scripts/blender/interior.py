"""A textured interior built in Blender and exported with Blender's glTF exporter, with the
sky behind its window, and Cycles' render of the same Blender scene as a reference.

    pip install bpy==5.0.1
    python3 scripts/blender/interior.py scenes/gltf-interior --spp 1024 --size 192x108

writes `sky.exr` (a latitude–longitude sky: blue above, a bright horizon, dark ground; also
the Blender world's environment texture), `scene.glb` (a 6 × 5 × 3 m room: a wooden floor
texture, a picture on a normal-mapped plaster back wall, a window in the right wall, a gold
sphere, a glass sphere, a pedestal, a spot light and a dim point light, Blender's camera; the
scene's custom property `tessera_environment` names the sky, exported as the glTF scene's
extras since glTF has no environment of its own) and, with `--spp` > 0, `cycles.exr`: Cycles'
path-traced render (no denoiser, Standard view transform, linear EXR) at `--size`.
"""

import argparse
import math
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(__file__))
from diffuse_shot import board, bumps, image, render_cycles, textured  # noqa: E402
from product_shot import principled  # noqa: E402


def normal_mapped(name, color, img):
    m = principled(name, color, roughness=0.9)
    nodes = m.node_tree.nodes
    img.colorspace_settings.name = "Non-Color"
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = img
    nm = nodes.new("ShaderNodeNormalMap")
    m.node_tree.links.new(tex.outputs["Color"], nm.inputs["Color"])
    m.node_tree.links.new(nm.outputs["Normal"], nodes["Principled BSDF"].inputs["Normal"])
    return m


def box(name, lo, hi, material):
    centre = [(a + b) / 2 for a, b in zip(lo, hi)]
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=centre)
    o = bpy.context.object
    o.scale = [b - a for a, b in zip(lo, hi)]
    bpy.ops.object.transform_apply(scale=True)
    o.data.materials.append(material)
    o.name = name
    return o


def plane(name, size, location, rotation, material):
    bpy.ops.mesh.primitive_plane_add(size=1.0, location=location, rotation=rotation)
    o = bpy.context.object
    o.scale = (size[0], size[1], 1.0)
    bpy.ops.object.transform_apply(scale=True)
    o.data.materials.append(material)
    o.name = name
    return o


def picture(x, y):
    if x < 6 or y < 6 or x >= 122 or y >= 122:
        return (0.2, 0.12, 0.05)
    # A landscape: sky, hills, a sun.
    if (x - 88) ** 2 + (y - 90) ** 2 < 100:
        return (1.0, 0.85, 0.4)
    hill = 40 + 12 * math.sin(x * 0.08)
    return (0.25, 0.5, 0.2) if y < hill else (0.45, 0.65, 0.95 - y / 400.0)


def sky(path, width=256, height=128):
    img = bpy.data.images.new("Sky", width, height, float_buffer=True, alpha=False)
    px = []
    for j in range(height):  # Blender rows go up from the bottom
        elevation = (j + 0.5) / height * math.pi - math.pi / 2
        for _ in range(width):
            if elevation < 0:
                c = (0.08, 0.07, 0.06)
            else:
                t = math.sin(elevation)
                c = (0.6 + 1.4 * (1 - t) ** 4, 0.75 + 1.2 * (1 - t) ** 4, 1.2 + 0.6 * (1 - t) ** 4)
            px.extend((*c, 1.0))
    img.pixels = px
    img.filepath_raw = path
    img.file_format = "OPEN_EXR"
    img.save()


def world(scene, sky_path):
    """The sky as the world's environment texture, for Cycles' reference."""
    w = bpy.data.worlds.new("Sky")
    w.use_nodes = True
    nodes = w.node_tree.nodes
    env = nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(sky_path)
    env.image.colorspace_settings.name = "Linear Rec.709"
    env.projection = "EQUIRECTANGULAR"
    w.node_tree.links.new(env.outputs["Color"], nodes["Background"].inputs["Color"])
    nodes["Background"].inputs["Strength"].default_value = 1.0
    scene.world = w
    # What Tessera reads from the glTF scene's extras.
    scene["tessera_environment"] = {"image": "sky.exr", "strength": 1.0, "rotation_deg": 0.0}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out", nargs="?", default="gltf-interior")
    ap.add_argument("--spp", type=int, default=0)
    ap.add_argument("--size", default="192x108")
    a = ap.parse_args()
    out = a.out
    os.makedirs(out, exist_ok=True)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    sky(os.path.abspath(os.path.join(out, "sky.exr")))
    world(scene, os.path.abspath(os.path.join(out, "sky.exr")))
    white = principled("Plaster", (0.8, 0.8, 0.78), roughness=0.9)

    # Floor with a wooden board texture, two images across the 6 m.
    floor = plane("Floor", (6, 5), (0, 0, 0), (0, 0, 0), textured("Wood", image("Boards", 256, board)))
    for loop in floor.data.uv_layers.active.data:
        loop.uv = (loop.uv[0] * 3.0, loop.uv[1] * 2.5)
    plane("Ceiling", (6, 5), (0, 0, 3), (math.pi, 0, 0), white)
    bumpy = plane("Back wall", (6, 3), (0, 2.5, 1.5), (math.radians(90), 0, 0),
                  normal_mapped("Bumpy plaster", (0.75, 0.7, 0.62), image("Bumps", 256, bumps)))
    for loop in bumpy.data.uv_layers.active.data:
        loop.uv = (loop.uv[0] * 6.0, loop.uv[1] * 3.0)
    plane("Front wall", (6, 3), (0, -2.5, 1.5), (math.radians(-90), 0, 0), white)
    plane("Left wall", (5, 3), (-3, 0, 1.5), (math.radians(90), 0, math.radians(-90)), white)
    # The right wall, around a 1.6 m × 1.2 m window centred at y = 0, z = 1.6.
    box("Right wall low", (3.0, -2.5, 0.0), (3.1, 2.5, 1.0), white)
    box("Right wall high", (3.0, -2.5, 2.2), (3.1, 2.5, 3.0), white)
    box("Right wall front", (3.0, -2.5, 1.0), (3.1, -0.8, 2.2), white)
    box("Right wall back", (3.0, 0.8, 1.0), (3.1, 2.5, 2.2), white)

    plane("Picture", (1.4, 1.0), (-0.8, 2.49, 1.7), (math.radians(90), 0, 0),
          textured("Painting", image("Landscape", 128, picture)))

    box("Pedestal", (0.5, 0.6, 0.0), (1.1, 1.2, 0.7), principled("Grey", (0.5, 0.5, 0.5), roughness=0.6))
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.3, location=(0.8, 0.9, 1.0), segments=48, ring_count=24)
    bpy.ops.object.shade_smooth()
    gold = bpy.context.object
    gold.data.materials.append(principled("Gold", (1.0, 0.78, 0.35), metallic=1.0, roughness=0.25))
    gold.name = "Gold sphere"
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.35, location=(-0.7, 0.4, 0.35), segments=48, ring_count=24)
    bpy.ops.object.shade_smooth()
    glass = bpy.context.object
    glass.data.materials.append(principled("Glass", (1, 1, 1), roughness=0.0, transmission=1.0))
    glass.name = "Glass sphere"

    spot = bpy.data.lights.new("Spot", type="SPOT")
    spot.energy = 300.0  # W
    spot.spot_size = math.radians(40)
    spot.spot_blend = 0.4
    key = bpy.data.objects.new("Spot", spot)
    key.location = (0.8, 0.9, 2.95)
    key.rotation_euler = (0, 0, 0)  # pointing straight down
    scene.collection.objects.link(key)
    fill = bpy.data.lights.new("Fill", type="POINT")
    fill.energy = 40.0  # W
    fill.shadow_soft_size = 0.0
    f = bpy.data.objects.new("Fill", fill)
    f.location = (-1.5, -1.5, 2.6)
    scene.collection.objects.link(f)

    cam = bpy.data.cameras.new("Camera")
    cam.sensor_fit = "VERTICAL"
    cam.angle_y = math.radians(55)
    camera = bpy.data.objects.new("Camera", cam)
    camera.location = (-2.3, -2.2, 1.5)
    camera.rotation_euler = (math.radians(86), 0, math.radians(-42))
    scene.collection.objects.link(camera)
    scene.camera = camera

    # The exported camera's aspect ratio is the render's.
    scene.render.resolution_x = 960
    scene.render.resolution_y = 540
    scene.render.resolution_percentage = 100
    bpy.ops.export_scene.gltf(
        filepath=os.path.join(out, "scene.glb"),
        export_format="GLB",
        export_cameras=True,
        export_lights=True,
        export_extras=True,
        export_import_convert_lighting_mode="SPEC",
        export_yup=True,
    )
    if a.spp > 0:
        w, h = (int(v) for v in a.size.split("x"))
        scene.render.resolution_x = w
        scene.render.resolution_y = h
        render_cycles(scene, a.spp, os.path.abspath(os.path.join(out, "cycles.exr")))


if __name__ == "__main__":
    main()
