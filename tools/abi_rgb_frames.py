#!/usr/bin/env python3
"""Relit frames through srug's C API with and without the scene's own colour.

Two renderers on one context render the same scene and camera with a fixed
sun, one frame each in turn: one with `1u << SRUG_CHANNEL_RGB` in its channel
mask (the splatted 3DGS colour as well, as every relit frame did before the
mask decided it), one without. Prints each frame's GPU milliseconds (the sum
of `srug_renderer_stage`) and the per-round ratio; the images must be the same
bytes. Uses examples/render_frame.py's loader.

    cargo build --release -p srug-bindings
    LP_NUM_THREADS=2 python3 tools/abi_rgb_frames.py SCENE.ply CAMERAS.json --rounds 12
"""
import argparse
import ctypes as C
import os
import statistics
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "examples"))
import render_frame as rf  # noqa: E402

SRUG_CHANNEL_RGB = 0


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scene")
    p.add_argument("cameras")
    p.add_argument("--index", type=int, default=0)
    p.add_argument("--rounds", type=int, default=12)
    p.add_argument("--size", default="704x192")
    p.add_argument("--library", default=os.environ.get("SRUG_LIBRARY"))
    a = p.parse_args()
    lib = rf.load(a.library or rf.default_library())
    lib.srug_renderer_set_camera_from_file.argtypes = [C.c_void_p, C.c_char_p, C.c_size_t, C.POINTER(C.c_size_t)]
    lib.srug_renderer_set_camera_from_file.restype = C.c_uint32
    width, height = (int(v) for v in a.size.split("x"))
    ctx, scene = C.c_void_p(), C.c_void_p()
    renderers = {"rgb": C.c_void_p(), "no rgb": C.c_void_p()}
    try:
        rf.check(lib, lib.srug_context_create(None, 0, C.byref(ctx)))
        rf.check(lib, lib.srug_scene_from_file(ctx, a.scene.encode(), C.byref(scene)))
        for name, r in renderers.items():
            mask = (1 << SRUG_CHANNEL_RGB) if name == "rgb" else 0
            rf.check(lib, lib.srug_renderer_create(ctx, width, height, mask, C.byref(r)))
            rf.check(lib, lib.srug_renderer_set_camera_from_file(r, a.cameras.encode(), a.index, None))
            rf.check(lib, lib.srug_renderer_set_sun(r, 260.0, 50.0, rf.vec3("3.14159,3.14159,3.14159")))

        def frame(r):
            rf.check(lib, lib.srug_renderer_render(r, scene))
            count, stages = C.c_size_t(), {}
            rf.check(lib, lib.srug_renderer_stage_count(r, C.byref(count)))
            for i in range(count.value):
                name, seconds = C.create_string_buffer(128), C.c_double()
                rf.check(lib, lib.srug_renderer_stage(r, i, name, len(name), C.byref(seconds)))
                stages[name.value.decode()] = stages.get(name.value.decode(), 0.0) + seconds.value
            return stages

        images = {}
        for name, r in renderers.items():
            frame(r)  # the shadow map, kept for the frames that follow
            image = (C.c_uint8 * (width * height * 4))()
            rf.check(lib, lib.srug_renderer_read_image(r, rf.SRUG_FORMAT_RGBA8_SRGB, image, len(image), 0))
            images[name] = bytes(image)
        if images["rgb"] != images["no rgb"]:
            sys.exit("the two renderers' images differ")
        times = {name: [] for name in renderers}
        stage_times = {name: {} for name in renderers}
        for _ in range(a.rounds):
            for name, r in renderers.items():
                stages = frame(r)
                times[name].append(sum(stages.values()))
                for s, t in stages.items():
                    stage_times[name].setdefault(s, []).append(t)
        ratios = [b / a for a, b in zip(times["rgb"], times["no rgb"])]
        for name in renderers:
            t = times[name]
            print(f"{name}: median {statistics.median(t) * 1e3:.1f} ms GPU a frame "
                  f"({min(t) * 1e3:.1f}-{max(t) * 1e3:.1f}), stages (median ms): "
                  + ", ".join(f"{s} {statistics.median(v) * 1e3:.1f}" for s, v in stage_times[name].items()))
        print(f"no rgb / rgb, per round: median {statistics.median(ratios):.3f} "
              f"({min(ratios):.3f}-{max(ratios):.3f}) over {a.rounds} rounds; images the same bytes")
    except rf.SrugError as e:
        sys.exit(f"srug: {e}")
    finally:
        for r in renderers.values():
            lib.srug_renderer_destroy(r)
        lib.srug_scene_destroy(scene)
        lib.srug_context_destroy(ctx)


if __name__ == "__main__":
    main()
