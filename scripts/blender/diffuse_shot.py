"""A diffuse product shot in Blender: exported with Blender's glTF exporter, and rendered by
Cycles as the independent reference Tessera's render of the export is compared with.

    pip install bpy==5.0.1
    python3 scripts/blender/diffuse_shot.py scenes/gltf/diffuse-shot [--spp 4096] [--size 160x90]
    python3 scripts/blender/diffuse_shot.py scenes/gltf/textured-shot --textured

`--textured` gives the floor a board texture (8×8 squares of two woods' colours, with a
grain), hangs a picture on the wall (a colour gradient with a frame), both 8-bit sRGB PNG
images, and gives the wall a tangent-space normal map of round bumps (8-bit, Non-Color), all
embedded by the exporter in the .glb (`textured-shot.glb`); tangents are left to the reader
(MikkTSpace), as Blender's exporter does by default.

writes `diffuse-shot.glb` and `cycles.exr` (linear Rec.709 radiance, Standard view transform,
no denoiser, no clamping, path tracing to depth 64) into the folder. Every material is
Lambertian in both renderers (Principled BSDF with Specular IOR Level 0, exported as
KHR_materials_specular factor 0), so what is compared is the importer: geometry, node
transforms, the camera, the lights' and the emitter's units, and light transport.
"""

import argparse
import math
import os

import bpy


def diffuse(name, color, emission=None, strength=0.0):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    b = m.node_tree.nodes["Principled BSDF"]
    b.inputs["Base Color"].default_value = (*color, 1.0)
    b.inputs["Metallic"].default_value = 0.0
    b.inputs["Roughness"].default_value = 1.0
    b.inputs["Specular IOR Level"].default_value = 0.0
    if emission is not None:
        b.inputs["Emission Color"].default_value = (*emission, 1.0)
        b.inputs["Emission Strength"].default_value = strength
    return m


def image(name, size, colour):
    """An sRGB image of `size`² whose texel (x, y) (y up, as Blender stores rows) is
    colour(x, y), packed into the .blend so that the exporter embeds it."""
    img = bpy.data.images.new(name, size, size, alpha=False)
    px = []
    for y in range(size):
        for x in range(size):
            r, g, b = colour(x, y)
            px.extend((r, g, b, 1.0))
    img.pixels = px
    img.pack()
    return img


def textured(name, img):
    m = diffuse(name, (1.0, 1.0, 1.0))
    nodes = m.node_tree.nodes
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = img
    tex.interpolation = "Linear"
    m.node_tree.links.new(tex.outputs["Color"], nodes["Principled BSDF"].inputs["Base Color"])
    return m


def bumps(x, y):
    """A tangent-space normal (encoded in [0, 1]) of a field of round bumps, 32 texels apart;
    y up, as Blender stores rows and as glTF's normal maps point."""
    k = 2.0 * math.pi / 32.0
    dx = 0.6 * math.cos(k * x) * math.sin(k * y)
    dy = 0.6 * math.sin(k * x) * math.cos(k * y)
    l = math.sqrt(dx * dx + dy * dy + 1.0)
    return (0.5 - 0.5 * dx / l, 0.5 - 0.5 * dy / l, 0.5 + 0.5 / l)


def bumpy(name, color, img):
    m = diffuse(name, color)
    nodes = m.node_tree.nodes
    img.colorspace_settings.name = "Non-Color"
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = img
    tex.interpolation = "Linear"
    nm = nodes.new("ShaderNodeNormalMap")
    nm.space = "TANGENT"
    nm.inputs["Strength"].default_value = 1.0
    m.node_tree.links.new(tex.outputs["Color"], nm.inputs["Color"])
    m.node_tree.links.new(nm.outputs["Normal"], nodes["Principled BSDF"].inputs["Normal"])
    return m


def board(x, y):
    cell = (x // 32 + y // 32) % 2
    grain = 0.06 * math.sin(x * 0.7 + 3.0 * math.sin(y * 0.05))
    base = (0.55, 0.36, 0.2) if cell else (0.8, 0.65, 0.45)
    return tuple(min(max(c + grain, 0.0), 1.0) for c in base)


def picture(x, y):
    if x < 8 or y < 8 or x >= 120 or y >= 120:
        return (0.15, 0.1, 0.05)
    return (x / 128.0, y / 128.0, 0.5 + 0.4 * math.sin(x * 0.2) * math.cos(y * 0.2))


def add(obj, material, name):
    obj.data.materials.append(material)
    obj.name = name


def build(width, height, textures):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene

    bpy.ops.mesh.primitive_plane_add(size=8.0, location=(0, 0, 0))
    floor = textured("Floor", image("Board", 256, board)) if textures else diffuse(
        "Floor", (0.6, 0.6, 0.6))
    add(bpy.context.object, floor, "Floor")
    if textures:
        bpy.ops.mesh.primitive_plane_add(size=1.6, location=(-1.2, 2.98, 2.2),
                                         rotation=(math.radians(90), 0, 0))
        add(bpy.context.object, textured("Picture", image("Picture", 128, picture)), "Picture")
    bpy.ops.mesh.primitive_plane_add(size=8.0, location=(0, 3.0, 4.0),
                                     rotation=(math.radians(90), 0, 0))
    wall = bumpy("Wall", (0.5, 0.55, 0.7), image("Bumps", 256, bumps)) if textures else diffuse(
        "Wall", (0.5, 0.55, 0.7))
    add(bpy.context.object, wall, "Wall")

    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.5, location=(-1.1, 0, 0.5), segments=48,
                                         ring_count=24)
    bpy.ops.object.shade_smooth()
    add(bpy.context.object, diffuse("Yellow", (0.8, 0.6, 0.2)), "Sphere")

    bpy.ops.mesh.primitive_cube_add(size=0.8, location=(0.1, 0.3, 0.4),
                                    rotation=(0, 0, math.radians(25)))
    add(bpy.context.object, diffuse("Red", (0.7, 0.1, 0.08)), "Cube")

    # A child of the cube: its placement goes through the node hierarchy.
    cube = bpy.context.object
    bpy.ops.mesh.primitive_cylinder_add(radius=0.25, depth=0.6, location=(1.3, -0.2, 0.3))
    cyl = bpy.context.object
    add(cyl, diffuse("Green", (0.1, 0.5, 0.15)), "Cylinder")
    cyl.parent = cube
    cyl.matrix_parent_inverse = cube.matrix_world.inverted()

    bpy.ops.mesh.primitive_plane_add(size=1.2, location=(1.5, 2.0, 2.5),
                                     rotation=(math.radians(60), 0, 0))
    add(bpy.context.object,
        diffuse("Panel", (0.0, 0.0, 0.0), emission=(1.0, 0.9, 0.8), strength=4.0), "Panel")

    spot = bpy.data.lights.new("Key", type="SPOT")
    spot.energy = 600.0  # W
    spot.spot_size = math.radians(60)
    spot.spot_blend = 0.0
    spot.shadow_soft_size = 0.0
    key = bpy.data.objects.new("Key", spot)
    key.location = (-2.5, -2.5, 4.0)
    key.rotation_euler = (math.radians(40), 0, math.radians(-45))
    scene.collection.objects.link(key)

    point = bpy.data.lights.new("Fill", type="POINT")
    point.energy = 100.0  # W
    point.shadow_soft_size = 0.0
    fill = bpy.data.objects.new("Fill", point)
    fill.location = (2.5, -2.0, 2.5)
    scene.collection.objects.link(fill)

    cam = bpy.data.cameras.new("Camera")
    cam.sensor_fit = "VERTICAL"
    cam.angle_y = math.radians(40)
    camera = bpy.data.objects.new("Camera", cam)
    camera.location = (0.0, -6.0, 2.4)
    camera.rotation_euler = (math.radians(74), 0, 0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    scene.render.resolution_x = width
    scene.render.resolution_y = height
    scene.render.resolution_percentage = 100
    return scene


def render_cycles(scene, spp, path):
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device = "CPU"
    c.samples = spp
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.max_bounces = 64
    c.diffuse_bounces = 64
    c.glossy_bounces = 64
    c.transmission_bounces = 64
    c.transparent_max_bounces = 64
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.caustics_reflective = True
    c.caustics_refractive = True
    c.filter_width = 1.5
    scene.render.threads_mode = "FIXED"
    scene.render.threads = 2
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    scene.render.film_transparent = False
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.image_settings.exr_codec = "ZIP"
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--spp", type=int, default=4096)
    ap.add_argument("--size", default="160x90")
    ap.add_argument("--textured", action="store_true")
    ap.add_argument(
        "--obj",
        action="store_true",
        help="also export the scene with Blender's OBJ exporter (OBJ + MTL, textures as PNG "
        "files beside it, Y up as glTF) and skip Cycles when --spp is 0",
    )
    a = ap.parse_args()
    w, h = (int(v) for v in a.size.split("x"))
    os.makedirs(a.out, exist_ok=True)
    scene = build(w, h, a.textured)
    name = "textured-shot.glb" if a.textured else "diffuse-shot.glb"
    bpy.ops.export_scene.gltf(
        filepath=os.path.join(a.out, name),
        export_format="GLB",
        export_cameras=True,
        export_lights=True,
        export_import_convert_lighting_mode="SPEC",
        export_yup=True,
    )
    if a.obj:
        for img in bpy.data.images:
            if img.packed_file is not None or img.source == "GENERATED":
                img.filepath_raw = os.path.abspath(os.path.join(a.out, img.name + ".png"))
                img.file_format = "PNG"
                img.save()
        bpy.ops.wm.obj_export(
            filepath=os.path.join(a.out, name.replace(".glb", ".obj")),
            export_materials=True,
            export_normals=True,
            export_uv=True,
            export_selected_objects=False,
            path_mode="STRIP",
            forward_axis="NEGATIVE_Z",
            up_axis="Y",
        )
    if a.spp > 0:
        render_cycles(scene, a.spp, os.path.abspath(os.path.join(a.out, "cycles.exr")))


if __name__ == "__main__":
    main()
