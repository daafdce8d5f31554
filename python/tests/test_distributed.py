"""srug.distributed on a real local Ray cluster (ray from PyPI; head and worker
processes on this machine, bound to 127.0.0.1 only): 32 cameras rendered across it equal
the single-process images bit for bit, also when a worker is killed mid-run
(its task is retried on another worker)."""

import json
import os
import time

import numpy as np
import pytest

import srug

# A single-node cluster on loopback only: Ray's own switch (read when ray is imported) makes every
# process bind and advertise 127.0.0.1 instead of the machine's address.
os.environ["RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"] = "0"
ray = pytest.importorskip("ray", reason="ray is in the package's test extras; pip install './python[test]'")
import srug.distributed  # noqa: E402 - after the ray check


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """The demo city as PLY and 32 street cameras (176x48) as INRIA cameras.json."""
    folder = tmp_path_factory.mktemp("distributed")
    scene, cams = srug.demo_city(20_000, seed=7, sh_degree=1)
    ply = folder / "city.ply"
    scene.save(ply)
    base = cams.viewmats[1].astype(np.float64)
    k = cams.Ks[1].astype(np.float64) / 4.0
    entries = []
    for i in range(32):
        r = base[:3, :3]
        centre = -(r.T @ base[:3, 3]) + [0.0, 0.6 * i, 0.0]  # walking up the street (+y)
        entries.append(
            {"id": i, "img_name": f"walk_{i:02d}", "width": 176, "height": 48, "position": centre.tolist(),
             "rotation": r.T.tolist(), "fx": k[0, 0], "fy": k[1, 1]}
        )
    cameras = folder / "cameras.json"
    cameras.write_text(json.dumps(entries))
    return folder, ply, cameras


@pytest.fixture(scope="module")
def cluster(files):
    folder = files[0]
    marker = folder / "killed_once"
    # Worker processes inherit this: the first task to run kills its own worker (srug.distributed._maybe_die).
    os.environ["SRUG_TEST_KILL_ONCE"] = str(marker)
    ray.init(
        num_cpus=2,
        include_dashboard=False,
        log_to_driver=False,
        configure_logging=False,
        runtime_env={"env_vars": {"SRUG_VALIDATION": os.environ.get("SRUG_VALIDATION", "0")}},
    )
    assert [n["NodeManagerAddress"] for n in ray.nodes()] == ["127.0.0.1"]
    yield marker
    ray.shutdown()
    os.environ.pop("SRUG_TEST_KILL_ONCE", None)


def test_a_ray_cluster_renders_like_one_process_even_when_a_worker_dies(files, cluster):
    _, ply, cameras = files
    marker = cluster
    dev = srug.Device()
    local = dev.render(srug.Scene.from_file(ply), srug.Cameras.from_file(cameras), channels=["rgb", "depth"])
    assert local["rgb"].shape == (32, 48, 176, 3)

    start = time.perf_counter()
    spread = srug.distributed.render(ply, cameras, channels=["rgb", "depth"], chunk=4)
    first = time.perf_counter() - start
    assert marker.exists(), "no worker was killed: the retry path did not run"
    for name in local:
        assert np.array_equal(spread[name], local[name]), name

    start = time.perf_counter()
    again = srug.distributed.render(ply, cameras, channels=["rgb", "depth"], chunk=4)
    second = time.perf_counter() - start
    for name in local:
        assert np.array_equal(again[name], local[name]), name
    print(f"32 cameras on Ray: {first:.1f} s with a worker killed and retried, {second:.1f} s warm")

    # Several worker processes took part: two tasks that overlap in time run in two processes.
    @ray.remote
    def pid_after(seconds):
        time.sleep(seconds)
        return os.getpid()

    assert len(set(ray.get([pid_after.remote(1.0), pid_after.remote(1.0)]))) == 2

    subset = srug.distributed.relight(ply, cameras, indices=[5, 1, 30], chunk=2, sun=(260.0, 50.0))
    full = dev.relight(srug.Scene.from_file(ply), srug.Cameras.from_file(cameras)[[5, 1, 30]], sun=(260.0, 50.0))
    assert np.array_equal(subset, full)
