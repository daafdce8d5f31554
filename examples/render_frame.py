#!/usr/bin/env python3
"""Render one relit frame through srug's C API with ctypes (no other packages).

For simulators written in Python: load libsrug_c.so, make a context, a scene
(a PLY file, or the built-in demo city), a renderer with a camera and a sun,
render, and copy the frame into a bytearray; here it is written as a PNG.

    cargo build --release -p srug-bindings
    python3 examples/render_frame.py --out frame.png
    python3 examples/render_frame.py --scene city.ply --eye 0,-30,20 --target 0,0,5 --out frame.png

The library is found with --library, else $SRUG_LIBRARY, else target/release or
target/debug of this checkout.
"""
import argparse
import ctypes as C
import os
import struct
import sys
import zlib

SRUG_OK = 0
SRUG_FORMAT_RGBA8_SRGB = 0
SRUG_CHANNEL_DEPTH = 2
SRUG_TONE_MAP_ACES = 2


class SrugError(RuntimeError):
    pass


def load(path):
    lib = C.CDLL(path)
    handle = C.c_void_p
    f3 = C.POINTER(C.c_float)
    signatures = {
        "srug_version": ([], C.c_char_p),
        "srug_abi_version": ([], C.c_uint32),
        "srug_status_name": ([C.c_uint32], C.c_char_p),
        "srug_last_error": ([C.c_char_p, C.c_size_t, C.POINTER(C.c_size_t)], C.c_uint32),
        "srug_context_create": ([C.c_char_p, C.c_uint32, C.POINTER(handle)], C.c_uint32),
        "srug_context_destroy": ([handle], C.c_uint32),
        "srug_context_device_name": ([handle, C.c_char_p, C.c_size_t, C.POINTER(C.c_size_t)], C.c_uint32),
        "srug_scene_from_file": ([handle, C.c_char_p, C.POINTER(handle)], C.c_uint32),
        "srug_scene_create_demo": ([handle, C.c_size_t, C.c_uint64, C.POINTER(handle)], C.c_uint32),
        "srug_scene_destroy": ([handle], C.c_uint32),
        "srug_renderer_create": ([handle, C.c_uint32, C.c_uint32, C.c_uint32, C.POINTER(handle)], C.c_uint32),
        "srug_renderer_destroy": ([handle], C.c_uint32),
        "srug_renderer_set_camera_look_at": ([handle, f3, f3, f3, C.c_float], C.c_uint32),
        "srug_renderer_set_sun": ([handle, C.c_float, C.c_float, f3], C.c_uint32),
        "srug_renderer_set_exposure": ([handle, C.c_float, C.c_uint32], C.c_uint32),
        "srug_renderer_render": ([handle, handle], C.c_uint32),
        "srug_renderer_read_image": ([handle, C.c_uint32, C.c_void_p, C.c_size_t, C.c_size_t], C.c_uint32),
        "srug_renderer_read_channel": ([handle, C.c_uint32, f3, C.c_size_t], C.c_uint32),
        "srug_renderer_stage_count": ([handle, C.POINTER(C.c_size_t)], C.c_uint32),
        "srug_renderer_stage": ([handle, C.c_size_t, C.c_char_p, C.c_size_t, C.POINTER(C.c_double)], C.c_uint32),
    }
    for name, (args, ret) in signatures.items():
        fn = getattr(lib, name)
        fn.argtypes, fn.restype = args, ret
    return lib


def check(lib, status):
    """Raises SrugError with the library's message unless status is SRUG_OK."""
    if status != SRUG_OK:
        buf = C.create_string_buffer(2048)
        lib.srug_last_error(buf, len(buf), None)
        raise SrugError(f"{lib.srug_status_name(status).decode()}: {buf.value.decode()}")


def vec3(text):
    values = [float(v) for v in text.split(",")]
    if len(values) != 3:
        raise argparse.ArgumentTypeError(f"{text!r} is not x,y,z")
    return (C.c_float * 3)(*values)


def write_png(path, width, height, rgba):
    rows = b"".join(b"\x00" + bytes(rgba[y * width * 4:(y + 1) * width * 4]) for y in range(height))

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0))
                + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))


def default_library():
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    for profile in ("release", "debug"):
        candidate = os.path.join(root, "target", profile, "libsrug_c.so")
        if os.path.exists(candidate):
            return candidate
    sys.exit("libsrug_c.so not found: build it with `cargo build --release -p srug-bindings` or pass --library")


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--library", default=os.environ.get("SRUG_LIBRARY"))
    p.add_argument("--scene", help="a 3DGS PLY file (default: the built-in demo city)")
    p.add_argument("--gaussians", type=int, default=20000, help="demo city size")
    p.add_argument("--size", default="704x192")
    p.add_argument("--eye", type=vec3, default=vec3("-40,-2,1.6"))
    p.add_argument("--target", type=vec3, default=vec3("0,-2,1.2"))
    p.add_argument("--fov", type=float, default=90.0, help="horizontal field of view, degrees")
    p.add_argument("--sun", default="260,50", help="azimuth,elevation in degrees")
    p.add_argument("--out", required=True, help="PNG file")
    a = p.parse_args()
    lib = load(a.library or default_library())
    width, height = (int(v) for v in a.size.split("x"))
    print(f"srug {lib.srug_version().decode()}, ABI {lib.srug_abi_version()}")

    ctx, scene, renderer = C.c_void_p(), C.c_void_p(), C.c_void_p()
    try:
        check(lib, lib.srug_context_create(None, 0, C.byref(ctx)))
        name = C.create_string_buffer(256)
        check(lib, lib.srug_context_device_name(ctx, name, len(name), None))
        print(f"device: {name.value.decode()}")
        if a.scene:
            check(lib, lib.srug_scene_from_file(ctx, a.scene.encode(), C.byref(scene)))
        else:
            check(lib, lib.srug_scene_create_demo(ctx, a.gaussians, 7, C.byref(scene)))
        check(lib, lib.srug_renderer_create(ctx, width, height, 1 << SRUG_CHANNEL_DEPTH, C.byref(renderer)))
        check(lib, lib.srug_renderer_set_camera_look_at(renderer, a.eye, a.target, vec3("0,0,1"), a.fov))
        azimuth, elevation = (float(v) for v in a.sun.split(","))
        check(lib, lib.srug_renderer_set_sun(renderer, azimuth, elevation, vec3("3.14159,3.14159,3.14159")))
        check(lib, lib.srug_renderer_set_exposure(renderer, 0.0, SRUG_TONE_MAP_ACES))
        check(lib, lib.srug_renderer_render(renderer, scene))

        frame = (C.c_uint8 * (width * height * 4))()
        check(lib, lib.srug_renderer_read_image(renderer, SRUG_FORMAT_RGBA8_SRGB, frame, len(frame), 0))
        depth = (C.c_float * (width * height))()
        check(lib, lib.srug_renderer_read_channel(renderer, SRUG_CHANNEL_DEPTH, depth, len(depth)))
        covered = [d for d in depth if d > 0]
        count, total = C.c_size_t(), 0.0
        check(lib, lib.srug_renderer_stage_count(renderer, C.byref(count)))
        for i in range(count.value):
            seconds = C.c_double()
            check(lib, lib.srug_renderer_stage(renderer, i, None, 0, C.byref(seconds)))
            total += seconds.value
        # Colour already includes the sky behind the scene; alpha is coverage (for compositing).
        # The PNG is for viewing, so it is written opaque.
        frame[3::4] = b"\xff" * (width * height)
        write_png(a.out, width, height, frame)
        print(f"{a.out}: {width}x{height}, {total * 1e3:.0f} ms GPU in {count.value} stages, "
              f"{len(covered)} covered pixels, median depth {sorted(covered)[len(covered) // 2]:.1f}"
              if covered else f"{a.out}: nothing visible")
    except SrugError as e:
        sys.exit(f"srug: {e}")
    finally:
        lib.srug_renderer_destroy(renderer)
        lib.srug_scene_destroy(scene)
        lib.srug_context_destroy(ctx)


if __name__ == "__main__":
    main()
