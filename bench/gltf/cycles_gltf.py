"""cycles_gltf.py - render a glTF file with Cycles, for bench/gltf/compare.sh.
Blender imports the file with its own glTF importer (materials become
Principled BSDFs, KHR_lights_punctual lights Blender lights, the camera the
scene camera).

  blender -b --factory-startup --python-exit-code 1 --python bench/gltf/cycles_gltf.py -- \
      MODEL.glb -o OUT.exr --width W --height H --spp N [--lambert ALBEDO] [--threads T] [--bounces B]

--lambert A: every material becomes a Diffuse BSDF of albedo A; a material
with emission also emits it (Emission strength x colour): from both faces
when the glTF material is doubleSided (Blender's importer then turns backface
culling off), else from the front face only (Geometry Backfacing), as
Tessera's emitters do. Used for
the comparison where both renderers have the same model (diffuse + emission).

Cycles settings as bench/cycles/render_scene.py (the `cycles` branch): CPU,
box pixel filter of width 1, no adaptive sampling, no denoising, no
clamping, Filter Glossy 0, caustics on, 64 bounces of every kind (Tessera's
default max_depth), view transform Standard, 32-bit float OpenEXR. Prints
"CYCLES render_s=S" after the render."""
import os
import sys
import time

import bpy
import numpy

# Blender 3.4's glTF importer uses numpy.bool, removed in Debian's numpy 1.24.
if not hasattr(numpy, "bool"):
    numpy.bool = bool


def parse(argv):
    a = {"width": 160, "height": 120, "spp": 256, "threads": 2, "bounces": 64, "lambert": None, "out": None, "model": None,
         "turn": False}
    i = 0
    while i < len(argv):
        k = argv[i]
        if k == "-o":
            a["out"] = argv[i + 1]
        elif k in ("--width", "--height", "--spp", "--threads", "--bounces"):
            a[k[2:]] = int(argv[i + 1])
        elif k == "--turn-camera":  # mirror the camera through the scene's centre plane y = 0 (Blender axes)
            a["turn"] = True
            i += 1
            continue
        elif k == "--lambert":
            a["lambert"] = float(argv[i + 1])
        else:
            a["model"] = k
            i += 1
            continue
        i += 2
    if not a["model"] or not a["out"]:
        sys.exit("usage: ... -- MODEL.glb -o OUT.exr [--width W --height H --spp N --lambert A]")
    return a


def lambertise(albedo):
    for m in bpy.data.materials:
        if not m.use_nodes:
            continue
        nt = m.node_tree
        p = next((n for n in nt.nodes if n.type == "BSDF_PRINCIPLED"), None)
        out = next((n for n in nt.nodes if n.type == "OUTPUT_MATERIAL"), None)
        if p is None or out is None:
            continue
        ec = tuple(p.inputs["Emission"].default_value)
        es = p.inputs["Emission Strength"].default_value
        nt.nodes.clear()  # a fresh tree: nothing of the importer's nodes stays in the way
        out = nt.nodes.new("ShaderNodeOutputMaterial")
        diff = nt.nodes.new("ShaderNodeBsdfDiffuse")
        diff.inputs["Color"].default_value = (albedo, albedo, albedo, 1)
        one_sided = m.use_backface_culling  # Blender's importer: glTF doubleSided false
        if es > 0 and max(ec[0], ec[1], ec[2]) > 0 and not one_sided:
            em = nt.nodes.new("ShaderNodeEmission")
            em.inputs["Color"].default_value = ec
            em.inputs["Strength"].default_value = es
            add = nt.nodes.new("ShaderNodeAddShader")
            nt.links.new(diff.outputs[0], add.inputs[0])
            nt.links.new(em.outputs[0], add.inputs[1])
            nt.links.new(add.outputs[0], out.inputs["Surface"])
        elif es > 0 and max(ec[0], ec[1], ec[2]) > 0:
            em = nt.nodes.new("ShaderNodeEmission")
            em.inputs["Color"].default_value = ec
            em.inputs["Strength"].default_value = es
            geo = nt.nodes.new("ShaderNodeNewGeometry")
            front = nt.nodes.new("ShaderNodeMixShader")  # backfacing: diffuse only
            add = nt.nodes.new("ShaderNodeAddShader")
            nt.links.new(diff.outputs[0], add.inputs[0])
            nt.links.new(em.outputs[0], add.inputs[1])
            nt.links.new(geo.outputs["Backfacing"], front.inputs[0])
            nt.links.new(add.outputs[0], front.inputs[1])
            nt.links.new(diff.outputs[0], front.inputs[2])
            nt.links.new(front.outputs[0], out.inputs["Surface"])
        else:
            nt.links.new(diff.outputs[0], out.inputs["Surface"])


def configure(a):
    scene = bpy.context.scene
    r = scene.render
    r.engine = "CYCLES"
    r.resolution_x, r.resolution_y, r.resolution_percentage = a["width"], a["height"], 100
    r.threads_mode, r.threads = "FIXED", a["threads"]
    r.use_compositing = r.use_sequencer = False
    r.film_transparent = False
    r.dither_intensity = 0.0
    c = scene.cycles
    c.device = "CPU"
    c.samples = a["spp"]
    c.use_adaptive_sampling = c.use_denoising = c.use_preview_denoising = False
    c.pixel_filter_type, c.filter_width = "BOX", 1.0
    c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
    c.blur_glossy = 0.0
    c.caustics_reflective = c.caustics_refractive = True
    for k in ("max_bounces", "diffuse_bounces", "glossy_bounces", "transmission_bounces", "volume_bounces",
              "transparent_max_bounces"):
        setattr(c, k, a["bounces"])
    c.seed, c.use_animated_seed = 1, False
    if scene.world is None:
        scene.world = bpy.data.worlds.new("black")
    scene.world.use_nodes = True
    bg = scene.world.node_tree.nodes.get("Background")
    if bg:
        bg.inputs["Strength"].default_value = 0.0  # glTF has no world: black, as in Tessera
    vs = scene.view_settings
    vs.view_transform, vs.look, vs.exposure, vs.gamma = "Standard", "None", 0.0, 1.0
    im = r.image_settings
    im.file_format, im.color_mode, im.color_depth = "OPEN_EXR", "RGB", "32"


def main():
    a = parse(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else [])
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=os.path.abspath(a["model"]))
    cams = [o for o in bpy.context.scene.objects if o.type == "CAMERA"]
    if not cams:
        sys.exit("%s: no camera" % a["model"])
    bpy.context.scene.camera = cams[0]
    if a["turn"]:
        import math
        cams[0].location.y = -cams[0].location.y
        cams[0].rotation_mode = "XYZ"
        e = cams[0].matrix_world.to_euler("XYZ")
        e.z += math.pi
        cams[0].rotation_euler = e
    if a["lambert"] is not None:
        lambertise(a["lambert"])
    configure(a)
    t0 = time.perf_counter()
    bpy.ops.render.render(write_still=False)
    s = time.perf_counter() - t0
    bpy.data.images["Render Result"].save_render(os.path.abspath(a["out"]), scene=bpy.context.scene)
    print("CYCLES render_s=%.2f" % s, flush=True)


main()
