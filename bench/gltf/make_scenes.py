"""make_scenes.py - the glTF test scenes of scenes/gltf, built in Blender and
written by Blender's own glTF exporter. Run from the repository root:
  blender -b --factory-startup --python-exit-code 1 --python bench/gltf/make_scenes.py
(bench/gltf/make_arrow.py makes scenes/gltf/arrow.png first.)"""
import math
import os
import bpy

OUT = os.path.abspath("scenes/gltf")


def reset():
    bpy.ops.wm.read_factory_settings(use_empty=True)


def principled(name, base=(0.8, 0.8, 0.8, 1), metallic=0.0, roughness=0.5, emission=None, strength=1.0):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    p = m.node_tree.nodes["Principled BSDF"]
    p.inputs["Base Color"].default_value = base
    p.inputs["Metallic"].default_value = metallic
    p.inputs["Roughness"].default_value = roughness
    if emission:
        p.inputs["Emission"].default_value = emission
        p.inputs["Emission Strength"].default_value = strength
    return m


def camera(loc, target, lens=50):
    bpy.ops.object.camera_add(location=loc)
    cam = bpy.context.object
    cam.data.lens = lens
    d = [target[i] - loc[i] for i in range(3)]
    import mathutils
    cam.rotation_euler = mathutils.Vector(d).to_track_quat("-Z", "Y").to_euler()
    bpy.context.scene.camera = cam
    return cam


def add(obj, mat):
    obj.data.materials.append(mat)


def export(name, fmt):
    bpy.context.scene.render.resolution_x = 640
    bpy.context.scene.render.resolution_y = 480
    bpy.ops.export_scene.gltf(filepath=os.path.join(OUT, name), export_format=fmt, export_cameras=True,
                              export_lights=True, export_apply=True, export_yup=True)


# 1. A smooth Suzanne (subdivided, smooth shaded) in gold on a grey floor, a sun.
reset()
bpy.ops.mesh.primitive_monkey_add(location=(0, 0, 1))
s = bpy.context.object
s.modifiers.new("sub", "SUBSURF").levels = 2
bpy.ops.object.shade_smooth()
add(s, principled("gold", (1.0, 0.77, 0.34, 1), metallic=1.0, roughness=0.3))
bpy.ops.mesh.primitive_plane_add(size=8)
add(bpy.context.object, principled("floor", (0.5, 0.5, 0.5, 1), roughness=0.9))
bpy.ops.object.light_add(type="SUN", location=(3, -3, 6))
bpy.context.object.data.energy = 3.0
bpy.context.object.rotation_euler = (math.radians(40), math.radians(20), math.radians(30))
camera((0, -5, 2.2), (0, 0, 0.9))
export("suzanne.glb", "GLB")

# 2. A plane with the arrow texture, facing the camera; separate .bin and .png.
reset()
bpy.ops.mesh.primitive_plane_add(size=2, location=(0, 0, 0), rotation=(math.radians(90), 0, 0))
pl = bpy.context.object
m = principled("arrow", roughness=1.0)
tex = m.node_tree.nodes.new("ShaderNodeTexImage")
tex.image = bpy.data.images.load(os.path.join(OUT, "arrow.png"))
m.node_tree.links.new(tex.outputs["Color"], m.node_tree.nodes["Principled BSDF"].inputs["Base Color"])
add(pl, m)
camera((0, -4, 0), (0, 0, 0), lens=50)
bpy.ops.object.light_add(type="POINT", location=(0, -3, 1))
bpy.context.object.data.energy = 200.0
export("arrow-plane.gltf", "GLTF_SEPARATE")

# 3. A closed box lit only by an emissive panel under its ceiling.
reset()
bpy.ops.mesh.primitive_cube_add(size=2, location=(0, 0, 1))
box = bpy.context.object
bpy.ops.object.mode_set(mode="EDIT")
bpy.ops.mesh.flip_normals()  # faces point inwards
bpy.ops.object.mode_set(mode="OBJECT")
add(box, principled("walls", (0.7, 0.7, 0.7, 1), roughness=1.0))
bpy.ops.mesh.primitive_plane_add(size=0.8, location=(0, 0, 1.98), rotation=(math.radians(180), 0, 0))
panel = principled("panel", (0, 0, 0, 1), roughness=1.0, emission=(1, 0.9, 0.8, 1), strength=10.0)
panel.use_backface_culling = True  # exported as doubleSided false: emits downwards only
add(bpy.context.object, panel)
bpy.ops.mesh.primitive_uv_sphere_add(radius=0.35, location=(-0.3, 0.2, 0.35), segments=48, ring_count=24)
bpy.ops.object.shade_smooth()
add(bpy.context.object, principled("ball", (0.2, 0.4, 0.8, 1), roughness=0.6))
camera((0, -0.99, 1.0), (0, 1, 1.0), lens=18)
export("emissive-box.glb", "GLB")
