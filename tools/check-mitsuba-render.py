#!/usr/bin/env python3
"""The half of tools/check-mitsuba that runs in the Mitsuba venv: render a scene dict, read EXRs.

Run by tools/check-mitsuba with the venv's python (see tools/mitsuba_venv.py), not by hand:

    VENV/bin/python tools/check-mitsuba-render.py --scene WORK/mitsuba-scene.json \
        --variant llvm_ad_rgb --exr WORK/mitsuba.exr --raw WORK/rt.exr WORK/rt.f32 ...

--scene is a JSON dict for mi.load_dict, except that every "to_world" is either
{"look_at": {"origin", "target", "up"}} or {"matrix": 4 rows of 4} (world from object, row-major);
the rendered image goes to --exr (linear RGB, float32). Each --raw EXR RAW pair converts an EXR
(either image) into RAW: float32 RGB, row-major, top row first, no header, for the system-python
side to read without an image library. The last line of stdout is one JSON object: mitsuba,
variant, import_s, load_s (mi.load_dict), render_s (mi.render), write_s.
"""

import argparse
import array
import json
import time

T_START = time.perf_counter()

import drjit as dr  # noqa: E402  (timed as part of import_s)
import mitsuba as mi  # noqa: E402


def parse_args():
    """Read the command line."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scene", required=True, help="the scene dict as JSON (see above)")
    p.add_argument("--variant", default="scalar_rgb", help="Mitsuba variant (default scalar_rgb)")
    p.add_argument("--exr", required=True, help="where the rendered image goes")
    p.add_argument("--raw", nargs=2, action="append", default=[], metavar=("EXR", "RAW"),
                   help="convert EXR to raw float32 RGB (repeatable)")
    return p.parse_args()


def with_transforms(value):
    """`value` with every {"look_at": ...} / {"matrix": ...} under a "to_world" key made a transform."""
    if isinstance(value, list):
        return [with_transforms(v) for v in value]
    if not isinstance(value, dict):
        return value
    result = {}
    for key, item in value.items():
        if key == "to_world" and "look_at" in item:
            result[key] = mi.ScalarTransform4f().look_at(**item["look_at"])
        elif key == "to_world" and "matrix" in item:
            result[key] = mi.ScalarTransform4f(item["matrix"])
        else:
            result[key] = with_transforms(item)
    return result


def write_raw(exr, raw):
    """EXR -> float32 RGB rows, top first."""
    bitmap = mi.Bitmap(exr).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32, srgb_gamma=False)
    with open(raw, "wb") as out:
        array.array("f", mi.TensorXf(bitmap).array).tofile(out)


def main():
    """Render, write, convert, and print the timings."""
    args = parse_args()
    mi.set_variant(args.variant)
    t0 = time.perf_counter()
    with open(args.scene) as f:
        scene_dict = with_transforms(json.load(f))
    scene = mi.load_dict(scene_dict)
    t1 = time.perf_counter()
    image = mi.render(scene, seed=0)
    dr.eval(image)  # the llvm variants trace lazily: time the whole render
    dr.sync_thread()
    t2 = time.perf_counter()
    mi.Bitmap(image).write(args.exr)
    for exr, raw in args.raw:
        write_raw(exr, raw)
    t3 = time.perf_counter()
    result = {"mitsuba": mi.__version__, "variant": mi.variant(), "import_s": t0 - T_START,
              "load_s": t1 - t0, "render_s": t2 - t1, "write_s": t3 - t2}
    # Mitsuba's log shares stdout: start a fresh line so the JSON is the last line on its own.
    print("\n" + json.dumps(result))


if __name__ == "__main__":
    main()
