"""Builds a product shot in Blender and exports it with Blender's own glTF exporter.

Run with the `bpy` package from PyPI (Blender as a Python module):

    pip install bpy==5.0.1
    python3 scripts/blender/product_shot.py scenes/gltf/product-shot.glb

The scene: a floor, a rough metal sphere, a red plastic cube, a glass sphere, a spot light,
a point light, an emissive panel and a camera. The .glb it writes is committed, so the test
suite reads a real exporter's file without needing Blender.
"""

import math
import sys

import bpy


def principled(name, color, metallic=0.0, roughness=0.5, transmission=0.0, ior=1.5,
               emission=None, strength=0.0):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    b = m.node_tree.nodes["Principled BSDF"]
    b.inputs["Base Color"].default_value = (*color, 1.0)
    b.inputs["Metallic"].default_value = metallic
    b.inputs["Roughness"].default_value = roughness
    b.inputs["IOR"].default_value = ior
    b.inputs["Transmission Weight"].default_value = transmission
    if emission is not None:
        b.inputs["Emission Color"].default_value = (*emission, 1.0)
        b.inputs["Emission Strength"].default_value = strength
    return m


def place(obj, material):
    obj.data.materials.append(material)
    return obj


def main(out):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene

    bpy.ops.mesh.primitive_plane_add(size=8.0, location=(0, 0, 0))
    place(bpy.context.object, principled("Floor", (0.6, 0.6, 0.6), 0.0, 0.8)).name = "Floor"

    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.5, location=(-1.1, 0, 0.5), segments=48,
                                         ring_count=24)
    bpy.ops.object.shade_smooth()
    place(bpy.context.object, principled("Brushed metal", (0.9, 0.7, 0.4), 1.0, 0.3)).name = "Metal"

    bpy.ops.mesh.primitive_cube_add(size=0.8, location=(0.1, 0.3, 0.4),
                                    rotation=(0, 0, math.radians(25)))
    place(bpy.context.object, principled("Red plastic", (0.7, 0.05, 0.04), 0.0, 0.4)).name = "Cube"

    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.4, location=(1.2, -0.3, 0.4), segments=48,
                                         ring_count=24)
    bpy.ops.object.shade_smooth()
    place(bpy.context.object,
          principled("Glass", (1.0, 1.0, 1.0), 0.0, 0.0, transmission=1.0, ior=1.5)).name = "Glass"

    bpy.ops.mesh.primitive_plane_add(size=1.5, location=(0, 2.5, 2.0),
                                     rotation=(math.radians(60), 0, 0))
    place(bpy.context.object,
          principled("Panel", (0.0, 0.0, 0.0), 0.0, 1.0, emission=(1.0, 0.9, 0.8),
                     strength=6.0)).name = "Panel"

    spot = bpy.data.lights.new("Key", type="SPOT")
    spot.energy = 800.0  # W
    spot.spot_size = math.radians(50)
    spot.spot_blend = 0.3
    key = bpy.data.objects.new("Key", spot)
    key.location = (-2.5, -2.5, 4.0)
    key.rotation_euler = (math.radians(40), 0, math.radians(-45))
    scene.collection.objects.link(key)

    point = bpy.data.lights.new("Fill", type="POINT")
    point.energy = 150.0  # W
    point.shadow_soft_size = 0.0
    fill = bpy.data.objects.new("Fill", point)
    fill.location = (2.5, -2.0, 2.5)
    scene.collection.objects.link(fill)

    cam = bpy.data.cameras.new("Camera")
    cam.sensor_fit = "VERTICAL"
    cam.angle_y = math.radians(35)
    camera = bpy.data.objects.new("Camera", cam)
    camera.location = (0.0, -6.0, 2.4)
    camera.rotation_euler = (math.radians(74), 0, 0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    scene.render.resolution_x = 960
    scene.render.resolution_y = 540

    bpy.ops.export_scene.gltf(
        filepath=out,
        export_format="GLB",
        export_cameras=True,
        export_lights=True,
        export_import_convert_lighting_mode="SPEC",
        export_yup=True,
    )


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "product-shot.glb")
