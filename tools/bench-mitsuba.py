#!/usr/bin/env python3
"""Render one OBJ with Mitsuba 3 the way tools/bench asks, and print its phase times as JSON.

The scene matches rt's "diffuse mesh + one point light" comparison: a perspective camera
(vertical fov), a diffuse mesh with smooth vertex normals, one point light, the `direct`
integrator with one emitter sample and no BSDF sample, and 1 sample per pixel, so each pixel
traces one camera ray and one shadow ray.

Run it with the Python of a venv that has mitsuba installed, e.g.

    VENV/bin/python tools/bench-mitsuba.py --obj dragon.obj --eye 0 0.125 0.3 \
        --target 0 0.125 0 --light 0.3 0.5 0.6

It prints one JSON object as the last line of stdout (Mitsuba's warnings may come before it): import_s (import mitsuba + set_variant), load_s
(mi.load_dict: OBJ parsing and BVH build), render_s (mi.render), write_s (only with --png),
triangles, and the mitsuba version. Whole-process time is measured by the caller.
"""

import argparse
import json
import time

T_START = time.perf_counter()

import mitsuba as mi  # noqa: E402  (timed as part of import_s)

mi.set_variant("scalar_rgb")
T_IMPORTED = time.perf_counter()


def parse_args():
    """Read the command line."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--obj", required=True, help="the mesh (Wavefront OBJ)")
    p.add_argument("--eye", type=float, nargs=3, required=True, metavar=("X", "Y", "Z"))
    p.add_argument("--target", type=float, nargs=3, required=True, metavar=("X", "Y", "Z"))
    p.add_argument("--up", type=float, nargs=3, default=[0.0, 1.0, 0.0], metavar=("X", "Y", "Z"))
    p.add_argument("--fovy", type=float, default=45.0, help="vertical field of view, degrees")
    p.add_argument("--width", type=int, default=1024)
    p.add_argument("--height", type=int, default=1024)
    p.add_argument("--light", type=float, nargs=3, required=True, metavar=("X", "Y", "Z"),
                   help="point light position")
    p.add_argument("--intensity", type=float, default=1.0, help="point light intensity")
    p.add_argument("--png", help="also write the image here (not timed as render)")
    return p.parse_args()


def scene_dict(args):
    """The Mitsuba scene description for load_dict."""
    return {
        "type": "scene",
        "integrator": {"type": "direct", "emitter_samples": 1, "bsdf_samples": 0},
        "sensor": {
            "type": "perspective",
            "fov": args.fovy,
            "fov_axis": "y",
            "to_world": mi.ScalarTransform4f().look_at(
                origin=args.eye, target=args.target, up=args.up),
            "film": {
                "type": "hdrfilm",
                "width": args.width,
                "height": args.height,
                "rfilter": {"type": "box"},
            },
            "sampler": {"type": "independent", "sample_count": 1},
        },
        "light": {
            "type": "point",
            "position": args.light,
            "intensity": {"type": "rgb", "value": [args.intensity] * 3},
        },
        "mesh": {
            "type": "obj",
            "filename": args.obj,
            # rt gives an OBJ without vn smooth vertex normals; so does Mitsuba without this flag.
            "face_normals": False,
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.8] * 3}},
        },
    }


def main():
    """Load, render, optionally write, and print the timings."""
    args = parse_args()
    t0 = time.perf_counter()
    scene = mi.load_dict(scene_dict(args))
    t1 = time.perf_counter()
    image = mi.render(scene)
    t2 = time.perf_counter()
    result = {
        "mitsuba": mi.__version__,
        "variant": mi.variant(),
        "triangles": sum(s.face_count() for s in scene.shapes()),
        "import_s": T_IMPORTED - T_START,
        "load_s": t1 - t0,
        "render_s": t2 - t1,
    }
    if args.png:
        mi.util.write_bitmap(args.png, image)
        result["write_s"] = time.perf_counter() - t2
    # Mitsuba's log also goes to stdout (and may leave a colour code without a newline): start a
    # fresh line, so the JSON is the last line on its own.
    print("\n" + json.dumps(result))


if __name__ == "__main__":
    main()
