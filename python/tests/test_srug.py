"""The srug Python package against independent references (a numpy EWA splat of
one Gaussian, files another path reads), determinism, threads and bad input.

Every test runs with the Khronos validation layer on (SRUG_VALIDATION=1 in the
test command, `validation=True` here) and fails on any message.
"""

import json
import os
import threading
import time

import numpy as np
import pytest

import srug

W, H, F = 64, 48, 60.0


@pytest.fixture(scope="module")
def city():
    return srug.demo_city(20_000, seed=7, sh_degree=1)


def identity_camera(width=W, height=H):
    K = np.array([[F, 0.0, width / 2], [0.0, F, height / 2], [0.0, 0.0, 1.0]])
    return srug.Cameras(np.eye(4), K, width, height)


def quat_matrix(q):
    w, x, y, z = q / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def test_one_gaussian_matches_a_numpy_ewa_splat(dev):
    """alpha, rgb and depth of one Gaussian equal the EWA splat computed here in
    float64 (docs/conventions.md: 0.3 px² dilation, α = min(0.99, o·e^−σ), α < 1/255 skipped),
    within 2e-5, inside the splat's 3σ box."""
    mean = np.array([0.3, -0.2, 4.0])
    quat = np.array([0.9, 0.1, 0.3, -0.2])
    scales = np.array([0.15, 0.1, 0.12])
    opacity, color, bg = 0.8, np.array([0.7, 0.4, 0.2]), np.array([0.1, 0.2, 0.3])
    scene = srug.Scene.from_arrays(mean[None], quat[None], scales[None], [opacity], colors=color[None])
    out = dev.render(scene, identity_camera(), channels=["rgb", "depth"], background=bg)
    R = quat_matrix(quat)
    cov = R @ np.diag(scales**2) @ R.T
    x, y, z = mean
    J = np.array([[F / z, 0, -F * x / z**2], [0, F / z, -F * y / z**2]])
    cov2 = J @ cov @ J.T + 0.3 * np.eye(2)
    centre = np.array([F * x / z + W / 2, F * y / z + H / 2])
    conic = np.linalg.inv(cov2)
    radius = np.ceil(3 * np.sqrt(np.linalg.eigvalsh(cov2).max()))
    px = np.stack(np.meshgrid(np.arange(W) + 0.5, np.arange(H) + 0.5), -1)
    d = px - centre
    power = -0.5 * np.einsum("hwi,ij,hwj->hw", d, conic, d)
    alpha = np.minimum(0.99, opacity * np.exp(power))
    alpha[alpha < 1 / 255] = 0.0
    inside = np.all(np.abs(d) <= radius, axis=-1)
    got = out["alpha"][0]
    assert np.abs(got - alpha)[inside].max() < 2e-5
    assert np.all(got[~inside] <= alpha[~inside] + 2e-5)
    rgb = alpha[..., None] * color + (1 - alpha[..., None]) * bg
    assert np.abs(out["rgb"][0] - rgb)[inside].max() < 2e-5
    assert np.abs(out["depth"][0] - alpha * z)[inside].max() < 1e-4
    assert got.max() > 0.5 and (got > 0).sum() > 50


def test_output_shapes_dtypes_and_every_channel(dev, city):
    scene, cams = city
    out = dev.render(scene, cams[:2], channels=["all", "rgb", "top_gaussian", "range"])
    n, (w, h) = 2, cams.sizes[0]
    for name, k in [("rgb", 3), ("normal", 3), ("albedo", 3)]:
        assert out[name].shape == (n, h, w, k) and out[name].dtype == np.float32
    for name in ["alpha", "depth", "median_depth", "roughness", "metallic", "ao", "visibility", "range"]:
        assert out[name].shape == (n, h, w) and out[name].dtype == np.float32
    ids = out["top_gaussian"]
    assert ids.dtype == np.uint32 and ids.shape == (n, h, w)
    covered = out["alpha"] > 0.5
    assert np.all(ids[covered] < scene.count)
    assert np.all(out["range"][covered] >= out["depth"][covered] - 1e-3)
    assert all(np.isfinite(v).all() for k, v in out.items() if k != "top_gaussian")


def test_cameras_from_arrays_equal_the_same_cameras_from_a_file(dev, city, tmp_path):
    """INRIA cameras.json written here from viewmats and Ks reads back as the same cameras:
    both render bit-identical images."""
    scene, cams = city
    view, K = cams.viewmats, cams.Ks
    entries = []
    for i, (m, k) in enumerate(zip(view, K)):
        r = m[:3, :3].astype(np.float64)
        t = m[:3, 3].astype(np.float64)
        entries.append(
            {
                "id": i,
                "img_name": f"cam{i}",
                "width": 704,
                "height": 192,
                "position": (-(r.T @ t)).tolist(),
                "rotation": r.T.tolist(),
                "fx": float(k[0, 0]),
                "fy": float(k[1, 1]),
            }
        )
    path = tmp_path / "cameras.json"
    path.write_text(json.dumps(entries))
    from_file = srug.Cameras.from_file(path)
    assert from_file.names == [f"cam{i}" for i in range(len(cams))]
    from_arrays = srug.Cameras(view, K, 704, 192)
    a = dev.render(scene, from_file, channels=["rgb", "depth"])
    b = dev.render(scene, from_arrays, channels=["rgb", "depth"])
    assert np.abs(a["rgb"] - b["rgb"]).max() <= 1e-5
    assert np.abs(a["alpha"] - b["alpha"]).max() <= 1e-5


def test_batches_are_bit_identical_to_single_cameras_in_any_order(dev, city):
    scene, cams = city
    batch = dev.render(scene, cams, channels=["rgb", "depth", "top_gaussian"])
    again = dev.render(scene, cams, channels=["rgb", "depth", "top_gaussian"])
    backward = dev.render(scene, cams[::-1], channels=["rgb", "depth", "top_gaussian"])
    for name in batch:
        assert np.array_equal(batch[name], again[name]), name
        assert np.array_equal(batch[name], backward[name][::-1]), name
    for i in range(len(cams)):
        one = dev.render(scene, cams[i], channels=["rgb", "depth", "top_gaussian"])
        for name in batch:
            assert np.array_equal(batch[name][i], one[name][0]), (name, i)


def test_relight_by_angles_time_and_outputs(dev, city):
    scene, cams = city
    two = cams[:2]
    radiance = dev.relight(scene, two, sun=(260.0, 50.0))
    display = dev.relight(scene, two, sun=(260.0, 50.0), output="display", exposure=0.5)
    assert radiance.shape == (2, 192, 704, 3) and radiance.dtype == np.float32
    assert np.isfinite(radiance).all() and radiance.max() > 0.1
    assert display.min() >= 0.0 and display.max() <= 1.0
    low = dev.relight(scene, two, sun=(100.0, 15.0))
    assert np.abs(low - radiance).mean() > 1e-3, "another sun lights the street differently"
    when = "2024-06-21T17:30+02:00"
    az, el = srug.sun_position(when, 48.85, 2.35)
    assert 250 < az < 270 and 35 < el < 45, (az, el)  # late afternoon in Paris, midsummer
    by_time = dev.relight(scene, two, time=when, latitude=48.85, longitude=2.35)
    by_angles = dev.relight(scene, two, sun=(az, el))
    assert np.array_equal(by_time, by_angles)
    fast = dev.relight(scene, two, preset="fast")
    assert fast.shape == radiance.shape, "a reduced render scale comes back at the camera's size"
    night = dev.relight(scene, two, sun=None)
    assert night.mean() < radiance.mean()


def test_panoramas_see_all_around(dev, city):
    scene, cams = city
    pano = cams[1].panoramas(256)
    assert pano.sizes == [(256, 128)] and pano.lenses == ["Equirectangular"]
    out = dev.render(scene, pano, channels=["depth", "range"])
    assert np.array_equal(out["depth"], out["range"]), "a panorama's depth is the distance"
    assert (out["alpha"] > 0.5).mean() > 0.4


def test_progress_timings_and_memory(dev, city):
    scene, cams = city
    calls = []
    dev.render(scene, cams, progress=lambda done, total: calls.append((done, total)))
    n = len(cams)
    assert calls == [(i + 1, n) for i in range(n)]
    timings = dev.last_timings()
    assert len(timings) == n and all(any(name == "blend" for name, _ in t) for t in timings)
    assert all(ms >= 0 for t in timings for _, ms in t)
    memory = dev.memory()
    assert memory["peak_bytes"] >= memory["current_bytes"] > 0
    assert memory["pooled_bytes"] > 0  # the render's working buffers, kept for reuse
    assert dev.release_pooled_memory() == memory["pooled_bytes"]
    assert dev.memory()["pooled_bytes"] == 0 and dev.release_pooled_memory() == 0
    w, h = cams.sizes[0]
    fresh = dev.memory()["fresh_allocations"]
    assert dev.render(scene, cams[:1])["rgb"].shape == (1, h, w, 3), "rendering goes on after the release"
    assert dev.memory()["fresh_allocations"] > fresh  # its working buffers were released: new memory

    def stop(done, total):
        raise KeyboardInterrupt("stop")

    with pytest.raises(KeyboardInterrupt):
        dev.render(scene, cams, progress=stop)


def test_threads_render_at_once_with_the_gil_released(dev, city):
    """Two threads render on one device while a third runs Python: the third
    keeps running inside the renders (the GIL is released while the GPU works),
    and the images equal a sequential run."""
    scene, cams = city
    expected = dev.render(scene, cams)["rgb"]
    results, errors, spans = {}, [], []
    stamps = []
    done = threading.Event()

    def spin():
        k = 0
        while not done.is_set():
            k += 1
            if k % 1000 == 0:
                stamps.append(time.perf_counter())

    def work(k):
        try:
            t0 = time.perf_counter()
            results[k] = dev.render(scene, cams)["rgb"]
            spans.append((t0, time.perf_counter()))
        except Exception as e:  # noqa: BLE001 - reported below
            errors.append(e)

    spinner = threading.Thread(target=spin)
    workers = [threading.Thread(target=work, args=(k,)) for k in range(2)]
    spinner.start()
    for t in workers:
        t.start()
    for t in workers:
        t.join()
    done.set()
    spinner.join()
    assert not errors, errors
    for k in range(2):
        assert np.array_equal(results[k], expected)
    # Python ran inside each render call, away from its edges (where the call holds the GIL briefly).
    for t0, t1 in spans:
        inside = sum(1 for s in stamps if t0 + 0.02 < s < t1 - 0.02)
        assert inside > 10, f"only {inside} thousand Python loop turns ran during a {t1 - t0:.2f} s render"


def test_bad_input_raises_clear_errors(dev, city):
    scene, cams = city

    def kind_of(call):
        with pytest.raises(srug.Error) as e:
            call()
        return e.value.kind, str(e.value)

    kind, text = kind_of(lambda: srug.Cameras(np.array([["a"] * 4] * 4), np.eye(3), 64, 48))
    assert kind == "invalid_argument" and "viewmats" in text and "dtype" in text
    kind, text = kind_of(lambda: srug.Cameras(np.eye(3), np.eye(3), 64, 48))
    assert "viewmats" in text and "shape" in text
    bad = np.eye(4)
    bad[0, 3] = np.nan
    kind, text = kind_of(lambda: srug.Cameras(bad, np.eye(3), 64, 48))
    assert "viewmats" in text and "nan" in text.lower()
    kind, text = kind_of(lambda: srug.Cameras(np.eye(4), np.array([[F, 1.0, 32], [0, F, 24], [0, 0, 1]]), 64, 48))
    assert "Ks[0]" in text and "skew" in text
    scaled = np.eye(4)
    scaled[:3, :3] *= 2.0
    kind, text = kind_of(lambda: srug.Cameras(scaled, np.diag([F, F, 1.0]), 64, 48))
    assert "camera 0" in text and "rotation" in text
    kind, text = kind_of(lambda: srug.Cameras(np.eye(4), np.eye(3), 0, 48))
    assert "width" in text
    kind, text = kind_of(lambda: dev.render(scene, cams, channels=["rgb", "sparkle"]))
    assert kind == "invalid_argument" and "sparkle" in text
    kind, text = kind_of(lambda: dev.render(scene, cams, tile=12))
    assert "tile" in text
    # A COLMAP model whose cameras have different sizes cannot be stacked into one array.
    colmap = os.path.join(os.path.dirname(__file__), "..", "..", "tests", "data", "cameras", "colmap", "text")
    mixed = srug.Cameras.from_file(colmap)
    assert len(set(mixed.sizes)) > 1
    kind, text = kind_of(lambda: dev.render(scene, mixed))
    assert "differs in size" in text
    assert dev.render(scene, mixed.resized(32, 24))["alpha"].shape == (len(mixed), 24, 32)
    kind, text = kind_of(lambda: srug.Scene.from_arrays(np.zeros((2, 3)), np.zeros((2, 4)), np.ones((2, 3)), [0.5, 0.5], colors=np.zeros((2, 3))))
    assert "quats row 0" in text
    kind, text = kind_of(lambda: srug.Scene.from_arrays(np.zeros((1, 3)), [[1, 0, 0, 0]], [[1, 1, 1]], [1.5], colors=[[0, 0, 0]]))
    assert "opacities" in text
    kind, text = kind_of(lambda: srug.Scene.from_file("/nonexistent/city.ply"))
    assert kind == "io" and "/nonexistent/city.ply" in text
    kind, text = kind_of(lambda: srug.Cameras.from_file(os.devnull))
    assert kind in ("invalid_argument", "bad_file")
    plain = srug.Scene.from_arrays(np.zeros((1, 3)) + [0, 0, 5], [[1, 0, 0, 0]], [[0.1] * 3], [0.5], colors=[[1, 0, 0]])
    kind, text = kind_of(lambda: dev.relight(plain, identity_camera()))
    assert "albedo" in text
    kind, text = kind_of(lambda: dev.relight(scene, cams[:1], environment="/nonexistent/sky.exr"))
    assert "/nonexistent/sky.exr" in text
    kind, text = kind_of(lambda: dev.relight(scene, cams[:1], preset="best"))
    assert "best" in text
    kind, text = kind_of(lambda: dev.relight(scene, cams[:1], time="2024-06-21T12:00+00:00"))
    assert "latitude" in text


def test_non_contiguous_and_float64_inputs_equal_float32(dev):
    rng = np.random.default_rng(3)
    n = 200
    means = rng.uniform([-1, -1, 3], [1, 1, 6], (n, 3))
    quats = rng.normal(size=(n, 4))
    scales = rng.uniform(0.02, 0.1, (n, 3))
    opac = rng.uniform(0.2, 0.9, n)
    cols = rng.uniform(0, 1, (n, 3))
    a = srug.Scene.from_arrays(means.astype(np.float32), quats.astype(np.float32), scales.astype(np.float32),
                               opac.astype(np.float32), colors=cols.astype(np.float32))
    # Fortran order and strided views of float64 arrays.
    wide = np.zeros((n, 8))
    wide[:, ::2] = quats
    strided = wide[:, ::2]
    assert not strided.flags["C_CONTIGUOUS"]
    b = srug.Scene.from_arrays(np.asfortranarray(means), strided, scales, opac, colors=np.asfortranarray(cols))
    cam = identity_camera()
    ra, rb = dev.render(a, cam), dev.render(b, cam)
    assert np.array_equal(ra["rgb"], rb["rgb"])
    assert ra["alpha"].max() > 0.5


def test_type_stubs_ship_with_the_package():
    folder = os.path.dirname(srug.__file__)
    assert os.path.isfile(os.path.join(folder, "py.typed"))
    assert os.path.isfile(os.path.join(folder, "_srug.pyi"))


def test_shadow_gradients_match_finite_differences(dev, shadow_problem):
    """V and dL/d(Gaussians) from Python on a ground of flat Gaussians under a
    cluster of occluders: for the occluder mean, occluder opacity and receiver
    height with the largest gradients, central differences of L = Σ w·V (each
    a fresh forward pass) agree within 10%. Expected depths (smooth) for both
    map and receivers; the ground's heights vary so no perturbed Gaussian sets the
    scene bounds the light camera is fitted to (those are not differentiated)."""
    p = shadow_problem
    means, quats, log_scales, sh = p["means"], p["quats"], p["log_scales"], p["sh"]
    cam, weights, kw = p["cam"], p["weights"], p["kw"]
    n, g0 = len(means), p["ground"]

    def scene_of(m, o):
        return srug.Scene.from_arrays(m, quats, log_scales, o, sh=sh, activated=False)

    logits = np.full(n, 3.0)

    def loss(m, o):
        return float((dev.shadow(scene_of(m, o), cam, **kw).visibility * weights).sum())

    st = dev.shadow(scene_of(means, logits), cam, **kw)
    v = st.visibility
    assert v.shape == (96, 128) and 0.005 < (v < 0.5).mean() < 0.5
    g = st.backward(weights)
    assert {k: a.shape for k, a in g.items()} == {
        "means": (n, 3), "log_scales": (n, 3), "rotations": (n, 4), "opacity_logits": (n,)
    }
    occluder = g0 + int(np.argmax(np.abs(g["means"][g0:, 0])))
    receiver = int(np.argmax(np.abs(g["means"][:g0, 2])))
    opaque = g0 + int(np.argmax(np.abs(g["opacity_logits"][g0:])))
    # The receiver's step is a tenth of its 1 cm thickness: its surface depth (the presets') bends
    # over a step of its whole thickness (h = 0.01 gave 8.3 against 10.03; 0.003, 0.001 and 3e-4
    # gave 9.81, 10.03 and 10.01).
    steps = [("means", occluder, 0, 0.02), ("means", receiver, 2, 0.001), ("opacity_logits", opaque, None, 0.05)]
    for name, i, j, h in steps:
        if name == "means":
            up, down = means.copy(), means.copy()
            up[i, j] += h
            down[i, j] -= h
            fd = (loss(up, logits) - loss(down, logits)) / (2 * h)
            analytic = g["means"][i, j]
        else:
            up, down = logits.copy(), logits.copy()
            up[i] += h
            down[i] -= h
            fd = (loss(means, up) - loss(means, down)) / (2 * h)
            analytic = g["opacity_logits"][i]
        assert abs(fd - analytic) <= 0.1 * abs(analytic), (name, i, j, fd, analytic)
    with pytest.raises(srug.Error):
        st.backward(np.ones((10, 10)))
    with pytest.raises(srug.Error):
        dev.shadow(scene_of(means, logits), cam, sun=(200.0, -5.0))
    # The geometric bias (slope-scaled, normal offset) changes V; bad values are refused.
    # A 0.3 m bias, as before the presets' 0.8: this small scene's occluders, 2 m up, leave
    # the ground about two dozen shadowed pixels under a 20° sun at 0.8 m.
    low = dict(sun=(200.0, 20.0), resolution=512, bias=0.3)
    plain = dev.shadow(scene_of(means, logits), cam, slope_bias=0.0, **low).visibility
    # Centre depths (not the preset's surface depths) for the receivers move V.
    centre = dev.shadow(scene_of(means, logits), cam, slope_bias=0.0, surface_depth=False, **low).visibility
    assert centre.shape == plain.shape and not np.array_equal(centre, plain)
    # A map read at one half's coverage casts from more of each splat's outline: no less shadow.
    half = dev.shadow(scene_of(means, logits), cam, slope_bias=0.0, map_coverage=0.5, **low).visibility
    assert not np.array_equal(half, plain) and (half < 0.5).sum() >= (plain < 0.5).sum()
    # Receivers from one half's coverage (the preset's 0.45): fewer pixels receive; V changes.
    fewer = dev.shadow(scene_of(means, logits), cam, slope_bias=0.0, receiver_coverage=0.5, **low)
    assert not np.array_equal(fewer.visibility, plain)
    assert all(np.isfinite(a).all() for a in fewer.backward(weights).values())
    sloped = dev.shadow(scene_of(means, logits), cam, slope_bias=3.0, normal_offset=1.0, **low).visibility
    assert sloped.shape == plain.shape and not np.array_equal(sloped, plain)
    assert (sloped < 0.5).sum() <= (plain < 0.5).sum()
    with pytest.raises(srug.Error) as e:
        dev.shadow(scene_of(means, logits), cam, slope_bias=-1.0, **low)
    assert "slope bias" in str(e.value)
    # The paper's depth test instead of PCF: V differs, and its gradients match too.
    hard = dev.shadow(scene_of(means, logits), cam, filter="depth", **low)
    assert not np.array_equal(hard.visibility, plain)
    gh = hard.backward(weights)
    assert all(np.isfinite(a).all() for a in gh.values())
    with pytest.raises(srug.Error) as e:
        dev.shadow(scene_of(means, logits), cam, filter="soft", **low)
    assert "shadow filter" in str(e.value)


def test_materials_from_arrays_relight_like_the_scene(dev, city):
    """A relightable scene rebuilt from its own arrays (logits, activated=False, materials
    included) relights bit-identically; without albedo it cannot be relit; activated
    materials give a brighter frame for a brighter albedo and are refused outside [0, 1]."""
    scene, cams = city
    a = scene.arrays()
    assert {"albedo", "roughness", "metallic", "ao", "visibility"} <= set(a)
    raw = {k: a[k] for k in ("albedo", "roughness", "metallic", "ao", "visibility", "normals") if k in a}
    rebuilt = srug.Scene.from_arrays(a["means"], a["quats"], a["log_scales"], a["opacity_logits"], sh=a["sh"],
                                     activated=False, **raw)
    assert np.array_equal(dev.relight(rebuilt, cams[:2]), dev.relight(scene, cams[:2]))
    plain = srug.Scene.from_arrays(a["means"], a["quats"], a["log_scales"], a["opacity_logits"], sh=a["sh"],
                                   activated=False)
    assert not plain.relightable
    with pytest.raises(srug.Error) as e:
        dev.relight(plain, cams[:1])
    assert "albedo" in str(e.value)
    n = scene.count
    scales, opacities = np.exp(a["log_scales"]), 1 / (1 + np.exp(-a["opacity_logits"]))

    def lit(albedo):
        return srug.Scene.from_arrays(a["means"], a["quats"], scales, opacities, sh=a["sh"], albedo=albedo,
                                      roughness=np.full(n, 0.6), metallic=np.zeros(n))

    dim, bright = dev.relight(lit(np.full((n, 3), 0.3)), cams[:1]), dev.relight(lit(np.full((n, 3), 0.9)), cams[:1])
    assert np.isfinite(dim).all() and bright.mean() > 1.5 * dim.mean()
    with pytest.raises(srug.Error) as e:
        lit(np.full((n, 3), 1.5))
    assert "albedo" in str(e.value)


def test_a_closed_device_refuses_work_and_a_with_block_closes_it(city):
    scene, cams = city
    with srug.Device() as d:
        assert d.render(scene, cams[:1])["rgb"].shape == (1, 192, 704, 3)
    assert d.closed
    with pytest.raises(srug.Error) as e:
        d.render(scene, cams[:1])
    assert "closed" in str(e.value) and e.value.kind == "invalid_argument"
    d.close()  # twice is harmless
    assert "closed" in repr(d)


def test_surface_depth_moves_depths_only(dev, city):
    """Surface depths (each pixel's ray against the splat's plane) change the
    depth channels and nothing else; relighting takes the option too."""
    scene, cams = city
    cam = cams[:1].resized(176, 48)
    names = ["rgb", "depth", "median_depth"]
    centre = dev.render(scene, cam, channels=names)
    surface = dev.render(scene, cam, channels=names, surface_depth=True)
    assert np.array_equal(centre["rgb"], surface["rgb"]) and np.array_equal(centre["alpha"], surface["alpha"])
    moved = np.abs(centre["median_depth"] - surface["median_depth"]) > 1e-3
    assert 0.01 < moved.mean(), moved.mean()
    # The median read where coverage reaches 0.7: fewer pixels hold one, the others' depths only.
    deeper = dev.render(scene, cam, channels=names, median_coverage=0.7)
    assert np.array_equal(centre["rgb"], deeper["rgb"]) and np.array_equal(centre["depth"], deeper["depth"])
    assert (deeper["median_depth"] > 0).sum() < (centre["median_depth"] > 0).sum()
    with pytest.raises(srug.Error) as e:
        dev.render(scene, cam, channels=names, median_coverage=0.0)
    assert "median coverage 0: must lie strictly between 0 and 1" in str(e.value)
    lit = dev.relight(scene, cam, sun=(260.0, 50.0))
    assert lit.shape == (1, 48, 176, 3) and np.isfinite(lit).all()
    # The presets' surface depths are the default: True changes nothing, False does.
    assert np.array_equal(lit, dev.relight(scene, cam, sun=(260.0, 50.0), surface_depth=True))
    centre_lit = dev.relight(scene, cam, sun=(260.0, 50.0), surface_depth=False)
    assert np.isfinite(centre_lit).all() and not np.array_equal(lit, centre_lit)
    fitted = dev.relight(scene, cam, sun=(260.0, 50.0), shadow_fit="view")
    assert fitted.shape == (1, 48, 176, 3) and np.isfinite(fitted).all()
    with pytest.raises(srug.Error) as e:
        dev.relight(scene, cam, sun=(260.0, 50.0), shadow_fit="tight")
    assert "scene, view or cascades" in str(e.value)


def test_relight_behind_your_meshes_composites(dev, city):
    """relight with a host depth: a mesh 5 m away over the left half hides
    the splats there, the right half is the plain relight's bit for bit; a
    black background gives premultiplied radiance (zero where no splat
    covers); the host depth does not outlive the call; the fast preset's
    half-size frames refuse one."""
    scene, cams = city
    cam = cams[:1].resized(176, 48)
    sun = (260.0, 50.0)
    open_img, open_a = dev.relight(scene, cam, sun=sun, background=(0, 0, 0), return_alpha=True)
    depth = np.zeros((48, 176), np.float32)
    depth[:, :88] = 5.0
    img, a = dev.relight(scene, cam, sun=sun, background=(0, 0, 0), host_depth=depth, return_alpha=True)
    assert img.shape == (1, 48, 176, 3) and a.shape == (1, 48, 176)
    assert (a[0, :, :88] + 0.05 < open_a[0, :, :88]).mean() > 0.5
    assert np.array_equal(a[0, :, 88:], open_a[0, :, 88:])
    assert np.array_equal(img[0, :, 88:], open_img[0, :, 88:])
    uncovered = a == 0
    assert uncovered.any() and np.all(img[uncovered] == 0)
    assert np.array_equal(dev.relight(scene, cam, sun=sun, background=(0, 0, 0)), open_img)
    with pytest.raises(srug.Error) as e:
        dev.relight(scene, cam, sun=sun, preset="fast", host_depth=depth)
    assert "half size" in str(e.value)
    with pytest.raises(srug.Error) as e:
        dev.relight(scene, cam, sun=sun, host_depth=depth[:, :10])
    assert "host_depth of shape" in str(e.value)


def test_host_depth_hides_the_splats_behind_your_meshes(dev, city):
    """A mesh 5 m away over the left half of the frame hides the splats there;
    the right half, where the host has nothing, is unchanged; the Vulkan
    encoding of the same depth gives the same frame; bad shapes and
    conventions raise."""
    scene, cams = city
    cam = cams[:1].resized(176, 48)
    open_ = dev.render(scene, cam, channels=["rgb"])
    depth = np.zeros((48, 176), np.float32)
    depth[:, :88] = 5.0
    hidden = dev.render(scene, cam, channels=["rgb"], host_depth=depth)
    assert (hidden["alpha"][0, :, :88] + 0.05 < open_["alpha"][0, :, :88]).mean() > 0.5
    assert np.array_equal(hidden["alpha"][0, :, 88:], open_["alpha"][0, :, 88:])
    near, far = 0.1, 500.0
    vulkan = np.where(depth > 0, far / (far - near) * (1 - near / np.maximum(depth, 1e-9)), 1.0).astype(np.float32)
    same = dev.render(scene, cam, channels=["rgb"], host_depth=vulkan[None], depth_convention="vulkan", near=near, far=far)
    assert np.array_equal(same["alpha"], hidden["alpha"])
    with pytest.raises(srug.Error) as e:
        dev.render(scene, cam, channels=["rgb"], host_depth=depth[:, :10])
    assert "host_depth of shape" in str(e.value)
    with pytest.raises(srug.Error):
        dev.render(scene, cam, channels=["rgb"], host_depth=depth, depth_convention="opengl")


def test_shadow_tiles_agree_and_bad_tiles_are_refused(dev, shadow_problem):
    """The shadow test at 8-pixel tiles (a faster backward where splats crowd tiles) gives V and
    gradients close to those at 16: a few pixels at depth edges differ (measured: 3 of 12,288 by
    more than 1e-3, mean 5.6e-6; gradients within 0.7% in norm). Other tile sizes are refused."""
    p = shadow_problem
    logits = np.full(len(p["means"]), 3.0)
    scene = srug.Scene.from_arrays(p["means"], p["quats"], p["log_scales"], logits, sh=p["sh"], activated=False)
    a = dev.shadow(scene, p["cam"], **p["kw"])
    b = dev.shadow(scene, p["cam"], tile=8, **p["kw"])
    d = np.abs(a.visibility - b.visibility)
    assert d.mean() < 1e-4 and (d > 1e-3).mean() < 1e-3, (d.mean(), (d > 1e-3).mean())
    ga, gb = a.backward(p["weights"]), b.backward(p["weights"])
    for name in ga:
        assert np.linalg.norm(ga[name] - gb[name]) <= 0.02 * np.linalg.norm(ga[name]), name
    with pytest.raises(srug.Error) as e:
        dev.shadow(scene, p["cam"], tile=12, **p["kw"])
    assert "tile" in str(e.value)


def test_load_scene_streams_to_the_device_and_reads_back_on_demand(dev, city, tmp_path):
    """`Device.load_scene` puts a PLY straight on the device (no host copy);
    its renders, metadata and, read back from the device, its arrays equal
    those of the same file read on the host."""
    scene, cams = city
    path = tmp_path / "city.ply"
    scene.save(str(path))
    on_host = srug.Scene.from_file(str(path))
    loaded = dev.load_scene(str(path))
    assert (len(loaded), loaded.sh_degree, loaded.relightable) == (len(on_host), on_host.sh_degree, on_host.relightable)
    assert loaded.bounds == on_host.bounds
    few = cams[:2]
    a = dev.render(loaded, few, channels=["rgb", "depth"])
    b = dev.render(on_host, few, channels=["rgb", "depth"])
    for name in ("rgb", "depth", "alpha"):
        assert np.array_equal(a[name], b[name]), name
    np.testing.assert_array_equal(
        dev.relight(loaded, few, sun=(260.0, 50.0)), dev.relight(on_host, few, sun=(260.0, 50.0))
    )
    arrays, expected = loaded.arrays(), on_host.arrays()
    assert sorted(arrays) == sorted(expected)
    for name in expected:
        assert np.array_equal(arrays[name], expected[name]), name
    # Saved from the device's copy, it reads back as the same scene.
    again = tmp_path / "again.ply"
    loaded.save(str(again))
    assert np.array_equal(srug.Scene.from_file(str(again)).arrays()["sh"], expected["sh"])
    with pytest.raises(srug.Error) as e:
        dev.load_scene(str(tmp_path / "missing.ply"))
    assert "missing.ply" in str(e.value)


def test_a_scrambled_scene_renders_as_listed_with_ids_in_file_order(dev, city, tmp_path):
    """A scene listed in no spatial order (as a trained scene's file is) goes onto the device
    along a Morton curve by default: the frames of its file order, its top_gaussian ids and
    arrays in file order; `order="file"` keeps the file's order."""
    scene, cams = city
    a = scene.arrays()
    n = scene.count
    perm = (np.arange(n, dtype=np.int64) * 7919 + 13) % n
    names = ("normals", "albedo", "roughness", "metallic", "ao", "visibility")
    scrambled = srug.Scene.from_arrays(
        a["means"][perm], a["quats"][perm], a["log_scales"][perm], a["opacity_logits"][perm], a["sh"][perm],
        activated=False, **{k: a[k][perm] for k in names if k in a},
    )
    path = tmp_path / "scrambled.ply"
    scrambled.save(str(path))
    few = cams[:2]
    channels = ["rgb", "depth", "top_gaussian"]
    arranged = dev.load_scene(str(path))
    listed = dev.load_scene(str(path), order="file")
    out, ref = dev.render(arranged, few, channels=channels), dev.render(listed, few, channels=channels)
    # The same frame up to splats whose depths tie (they blend in listed order): PSNR above 50 dB.
    for name in ("rgb", "alpha", "depth"):
        mse = float(np.mean((out[name] - ref[name]) ** 2)) / max(float(np.max(ref[name])) ** 2, 1e-12)
        assert mse < 1e-5, (name, mse)
    ids, ref_ids = out["top_gaussian"], ref["top_gaussian"]
    assert (ids != ref_ids).mean() < 1e-3, (ids != ref_ids).mean()
    assert (ref_ids[ref["alpha"] > 0.5] < n).all() and (ref["alpha"] > 0.5).mean() > 0.5
    for name, v in arranged.arrays().items():
        assert np.array_equal(v, a[name][perm]), name
    # Scenes from arrays and host files take the same choice: the same order, the same bits.
    listed_arrays = srug.Scene.from_arrays(
        a["means"][perm], a["quats"][perm], a["log_scales"][perm], a["opacity_logits"][perm], a["sh"][perm],
        activated=False, order="file", **{k: a[k][perm] for k in names if k in a},
    )
    for other, same in ((listed_arrays, ref), (scrambled, out), (srug.Scene.from_file(str(path), order="file"), ref)):
        got = dev.render(other, few, channels=channels)
        assert all(np.array_equal(got[k], same[k]) for k in same), "another order than the same choice's"
    with pytest.raises(srug.Error) as e:
        dev.load_scene(str(path), order="hilbert")
    assert "hilbert" in str(e.value)
    with pytest.raises(srug.Error) as e:
        srug.Scene.from_file(str(path), order="z-curve")
    assert "z-curve" in str(e.value)


def test_shadow_cull_relights_alike(dev, city):
    """A shadow map splatted only where the frame looks gives the same frames."""
    scene, cams = city
    few = cams[:2]
    a = dev.relight(scene, few, sun=(250.0, 40.0))
    b = dev.relight(scene, few, sun=(250.0, 40.0), shadow_cull=True)
    np.testing.assert_array_equal(a, b)


def test_relight_shadow_options_override_the_preset(dev, city):
    """The shadow options of relight: the preset's own values change nothing,
    others change the frame, bad ones raise naming the option."""
    scene, cams = city
    one = cams[0]
    base = dev.relight(scene, one, sun=(250.0, 30.0))
    same = dev.relight(
        scene, one, sun=(250.0, 30.0), shadow_resolution=2048, shadow_k=50.0, shadow_bias=0.8,
        shadow_slope_bias=3.0, shadow_normal_offset=0.0, receiver_depth="median", shadow_test="sigmoid",
        shadow_filter="pcf", surface_depth=True, map_surface_depth=False,
    )
    np.testing.assert_array_equal(base, same)
    hard = dev.relight(scene, one, sun=(250.0, 30.0), shadow_filter="depth")
    assert not np.array_equal(base, hard)
    for surface in [dict(surface_depth=False), dict(map_surface_depth=True), dict(map_coverage=0.5),
                    dict(receiver_coverage=0.5)]:
        other = dev.relight(scene, one, sun=(250.0, 30.0), **surface)
        assert np.isfinite(other).all() and not np.array_equal(base, other), surface
    cascaded = dev.relight(scene, one, sun=(250.0, 30.0), shadow_fit="cascades", shadow_cascades=2)
    assert np.isfinite(cascaded).all() and not np.array_equal(base, cascaded)
    assert np.abs(cascaded - base).mean() < 0.05 * np.abs(base).mean()
    coarse = dev.relight(scene, one, sun=(250.0, 30.0), shadow_resolution=128, shadow_bias=0.0)
    assert not np.array_equal(base, coarse)
    traced = dev.relight(scene, one, sun=(250.0, 30.0), shadow_test="traced")
    assert np.isfinite(traced).all() and not np.array_equal(base, traced)
    for kwargs, word in [
        ({"shadow_resolution": 3}, "resolution"),
        ({"shadow_test": "exact"}, "shadow test"),
        ({"receiver_depth": "deepest"}, "depth mode"),
        ({"shadow_k": -1.0}, "sharpness"),
        ({"shadow_filter": "soft"}, "shadow filter"),
        ({"map_coverage": 1.0}, "shadow map coverage 1: must lie strictly between 0 and 1"),
        ({"receiver_coverage": 0.0}, "shadow receiver coverage 0: must lie strictly between 0 and 1"),
        ({"shadow_fit": "cascades", "shadow_cascades": 9}, "cascades"),
    ]:
        with pytest.raises(srug.Error) as e:
            dev.relight(scene, one, sun=(250.0, 30.0), **kwargs)
        assert word in str(e.value), (kwargs, str(e.value))
