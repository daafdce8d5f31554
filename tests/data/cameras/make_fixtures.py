"""Writes the camera fixtures in this folder with pycolmap (scripts/camera-fixtures.sh).

colmap/text and colmap/bin: one sparse model, written by pycolmap in both encodings: five
perspective cameras (PINHOLE, SIMPLE_PINHOLE, and SIMPLE_RADIAL, OPENCV, FOV with zero
distortion) and ten images with random poses. colmap_distorted/text: OPENCV with distortion and
OPENCV_FISHEYE (srug refuses both until it renders lenses). projections.json: for every image,
world points and their pixels as pycolmap projects them. transforms.json: the same cameras in
nerfstudio's layout, converted as nerfstudio's colmap_to_json does with the original world kept.
"""
import json
import os
import sys

import numpy as np
import pycolmap

try:
    import cv2
except ImportError:
    cv2 = None

out = sys.argv[1] if len(sys.argv) > 1 else "."
rng = np.random.default_rng(33)


def random_pose():
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    rot = pycolmap.Rotation3d(q[[1, 2, 3, 0]])  # xyzw
    return pycolmap.Rigid3d(rot, rng.uniform(-20, 20, size=3))


def model(cameras, images_per_camera):
    r = pycolmap.Reconstruction()
    for c in cameras:
        r.add_camera_with_trivial_rig(c)
    image_id = 1
    for c in cameras:
        for _ in range(images_per_camera):
            im = pycolmap.Image(name=f"cam{c.camera_id}_{image_id:03d}.png", camera_id=c.camera_id, image_id=image_id)
            r.add_image_with_trivial_frame(im, random_pose())
            image_id += 1
    return r


cameras = [
    pycolmap.Camera(model="PINHOLE", width=704, height=192, params=[400.0, 410.5, 350.5, 97.25], camera_id=1),
    pycolmap.Camera(model="SIMPLE_PINHOLE", width=640, height=480, params=[500.0, 322.0, 241.5], camera_id=2),
    pycolmap.Camera(model="SIMPLE_RADIAL", width=1024, height=768, params=[800.0, 510.0, 380.0, 0.0], camera_id=3),
    pycolmap.Camera(model="OPENCV", width=800, height=600, params=[600.0, 590.0, 401.0, 299.0, 0, 0, 0, 0], camera_id=4),
    pycolmap.Camera(model="FOV", width=320, height=240, params=[250.0, 251.0, 160.5, 119.5, 0.0], camera_id=5),
]
rec = model(cameras, 2)
for sub, write in [("colmap/text", rec.write_text), ("colmap/bin", rec.write_binary)]:
    os.makedirs(os.path.join(out, sub), exist_ok=True)
    write(os.path.join(out, sub))

distorted = model([
    pycolmap.Camera(model="OPENCV", width=800, height=600, params=[600.0, 590.0, 401.0, 299.0, -0.1, 0.02, 0.001, -0.002], camera_id=1),
    pycolmap.Camera(model="OPENCV_FISHEYE", width=1400, height=1400, params=[350.0, 350.0, 700.0, 700.0, 0.01, -0.002, 0.0, 0.0], camera_id=2),
], 1)
os.makedirs(os.path.join(out, "colmap_distorted/text"), exist_ok=True)
distorted.write_text(os.path.join(out, "colmap_distorted/text"))

projections = {}
frames = []
for image_id in sorted(rec.images):
    im = rec.images[image_id]
    cam = rec.cameras[im.camera_id]
    cam_from_world = im.cam_from_world()
    world_from_cam = cam_from_world.inverse()
    pts, pix = [], []
    while len(pts) < 8:
        # A point in front of the camera, within its view.
        uv = rng.uniform([0, 0], [cam.width, cam.height])
        ray = cam.cam_from_img(uv)
        p_cam = np.array([ray[0], ray[1], 1.0]) * rng.uniform(2, 60)
        p_world = world_from_cam * p_cam
        px = cam.img_from_cam(cam_from_world * p_world)
        pts.append(list(map(float, p_world)))
        pix.append(list(map(float, px)))
    projections[im.name] = {"points": pts, "pixels": pix}
    w2c = np.eye(4)
    w2c[:3, :4] = cam_from_world.matrix()
    c2w = np.linalg.inv(w2c)
    c2w[0:3, 1:3] *= -1
    fx, fy, cx, cy = cam.focal_length_x, cam.focal_length_y, cam.principal_point_x, cam.principal_point_y
    frames.append({
        "file_path": f"images/{im.name}", "transform_matrix": c2w.tolist(),
        "fl_x": fx, "fl_y": fy, "cx": cx, "cy": cy, "w": cam.width, "h": cam.height,
    })
with open(os.path.join(out, "projections.json"), "w") as f:
    json.dump(projections, f, indent=1)
with open(os.path.join(out, "transforms.json"), "w") as f:
    json.dump({"camera_model": "OPENCV", "k1": 0.0, "k2": 0.0, "p1": 0.0, "p2": 0.0, "frames": frames}, f, indent=1)
print("pycolmap", pycolmap.__version__, "wrote", out)

# Lens models: pycolmap's projection of camera-space points (and back to rays) for each model srug parses.
lens_cases = [
    ("SIMPLE_RADIAL", [800.0, 512.0, 384.0, -0.08], 50),
    ("RADIAL", [800.0, 512.0, 384.0, -0.1, 0.03], 50),
    ("OPENCV", [600.0, 590.0, 401.0, 299.0, -0.1, 0.02, 0.001, -0.002], 50),
    ("FULL_OPENCV", [600.0, 590.0, 401.0, 299.0, -0.2, 0.05, 0.001, -0.002, 0.01, 0.05, 0.01, 0.002], 50),
    ("OPENCV_FISHEYE", [350.0, 352.0, 700.0, 699.0, 0.01, -0.002, 0.0003, -0.00004], 89),
    ("SIMPLE_RADIAL_FISHEYE", [350.0, 700.0, 699.0, 0.01], 89),
    ("RADIAL_FISHEYE", [350.0, 700.0, 699.0, 0.01, -0.002], 89),
    ("SIMPLE_FISHEYE", [350.0, 700.0, 699.0], 89),
    ("FISHEYE", [350.0, 352.0, 700.0, 699.0], 89),
    ("FOV", [500.0, 505.0, 400.0, 300.0, 0.9], 50),
    ("EUCM", [300.0, 302.0, 700.0, 699.0, 0.6, 1.1], 75),
    ("SIMPLE_DIVISION", [600.0, 700.0, 699.0, -0.2], 50),
    ("DIVISION", [600.0, 605.0, 700.0, 699.0, 0.05], 45),
    ("THIN_PRISM_FISHEYE", [350.0, 352.0, 700.0, 699.0, 0.01, -0.002, 0.001, -0.0005, 0.0003, -0.00004, 0.0008, -0.0006], 80),
    ("RAD_TAN_THIN_PRISM_FISHEYE", [350.0, 352.0, 700.0, 699.0, 0.01, -0.002, 0.0003, -0.00004, 0.00001, -0.000002,
                                    0.001, -0.0005, 0.0008, -0.0006, 0.0002, -0.0001], 80),
    ("EQUIRECTANGULAR", [1400.0, 700.0], 180),
]
lenses = []
for name, params, max_deg in lens_cases:
    cam = pycolmap.Camera(model=name, width=1400, height=700 if name == "EQUIRECTANGULAR" else 1400, params=params)
    pts, pix, rays = [], [], []
    for _ in range(40):
        theta = np.radians(rng.uniform(0, max_deg))
        phi = rng.uniform(0, 2 * np.pi)
        d = np.array([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)]) * rng.uniform(1, 50)
        px = cam.img_from_cam(d)
        # Equirectangular pixels see behind the camera: the unit ray, not (x/z, y/z).
        ray = cam.cam_ray_from_img(px) if name == "EQUIRECTANGULAR" else cam.cam_from_img(px)
        pts.append(list(map(float, d)))
        pix.append(list(map(float, px)))
        rays.append(list(map(float, ray)))
    case = {"model": name, "params": params, "points": pts, "pixels": pix,
            "directions" if name == "EQUIRECTANGULAR" else "rays": rays}
    # OpenCV's own projection of the same points, for the models it defines.
    if cv2 is not None and name in ("OPENCV", "FULL_OPENCV", "OPENCV_FISHEYE"):
        fx, fy, cx, cy = params[:4]
        K = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1]], dtype=np.float64)
        obj = np.array(pts, dtype=np.float64).reshape(-1, 1, 3)
        zero = np.zeros(3)
        if name == "OPENCV_FISHEYE":
            cv, _ = cv2.fisheye.projectPoints(obj, zero, zero, K, np.array(params[4:8], dtype=np.float64))
        else:
            k1, k2, p1, p2 = params[4:8]
            rest = params[8:12] if name == "FULL_OPENCV" else [0.0, 0.0, 0.0, 0.0]
            dist = np.array([k1, k2, p1, p2, rest[0], rest[1], rest[2], rest[3]], dtype=np.float64)
            cv, _ = cv2.projectPoints(obj, zero, zero, K, dist)
        case["opencv_pixels"] = cv.reshape(-1, 2).tolist()
        case["opencv_version"] = cv2.__version__
    lenses.append(case)
with open(os.path.join(out, "lenses.json"), "w") as f:
    json.dump(lenses, f, indent=1)
