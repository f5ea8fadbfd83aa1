"""Where the environments render (``device=``): the CPU by default and unchanged, a bad name
refused naming the choices, ``auto`` on the CPU without a hardware GPU, and the GPU renderer
(on Mesa's software adapter where there is no GPU) giving the CPU's observations."""

import os
import subprocess
import sys

import numpy as np
import pytest

import sage3d
from conftest import SMALL_ENV, make_small_env as make

ALL = ["rgb", "depth", "semantic", "instance"]


pytestmark = pytest.mark.usefixtures("synth_cache")


def psnr(a, b):
    mse = np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2)
    return float("inf") if mse == 0 else 10 * np.log10(255.0**2 / mse)


def assert_close(cpu, gpu):
    """The GPU's observation has the CPU's keys, shapes and types; RGB within 40 dB PSNR,
    depth and the labels there are equal almost everywhere."""
    assert cpu.keys() == gpu.keys()
    for k in cpu:
        if k == "instruction":
            assert cpu[k] == gpu[k]
            continue
        assert (cpu[k].shape, cpu[k].dtype) == (gpu[k].shape, gpu[k].dtype), k
    np.testing.assert_array_equal(cpu["pose"], gpu["pose"])
    assert np.mean(np.abs(cpu["rgb"].astype(np.float64) - gpu["rgb"])) < 2.0
    assert psnr(cpu["rgb"], gpu["rgb"]) >= 40.0
    d_cpu, d_gpu = cpu["depth"], gpu["depth"]
    near = np.abs(d_cpu - d_gpu) <= 0.01 * np.maximum(d_cpu, d_gpu) + 1e-3
    assert near.mean() >= 0.98, f"depth close at {near.mean():.3f} of the pixels"
    for k in ("semantic", "instance"):
        if k in cpu:
            assert (cpu[k] == gpu[k]).mean() >= 0.98, k


def test_the_cpu_is_the_default_and_renders_as_before():
    default, cpu = make(), make(device="cpu")
    assert default.render_device.startswith("cpu (") and cpu.render_device.startswith("cpu (")
    a, _ = default.reset(options={"episode_index": 1})
    b, _ = cpu.reset(options={"episode_index": 1})
    for k in ("rgb", "depth", "pose"):
        np.testing.assert_array_equal(a[k], b[k])
    assert sage3d.env_config()["device"] == "cpu"
    # An environment that renders nothing has no renderer to name.
    assert make(sensors=[], device="gpu").render_device is None


def test_an_unknown_device_is_a_value_error_naming_the_choices():
    for build in (lambda: make(device="bogus"), lambda: sage3d.make_vec_env(2, **SMALL_ENV, device="bogus")):
        with pytest.raises(ValueError, match="'bogus'.*cpu, gpu, auto"):
            build()
    with pytest.raises(ValueError, match="cpu, gpu, auto"):
        sage3d.evaluate("no-dataset", agent="oracle", out="no-run", device="tpu")
    # Through the config dict the Rust side refuses it, naming the field.
    with pytest.raises(ValueError, match="device.*tpu.*cpu, gpu, auto"):
        make(config={"device": "tpu"})


def test_auto_takes_only_a_hardware_gpu():
    env = make(device="auto")
    device = env.render_device
    if device.startswith("gpu: "):
        assert "software" not in device, device
    else:
        assert device.startswith("cpu (") and "auto: " in device, device
    obs, _ = env.reset(options={"episode_index": 0})
    assert obs["rgb"].shape == (24, 32, 3)


def test_gpu_without_an_adapter_is_a_value_error_at_construction():
    code = (
        "import sage3d\n"
        "try:\n"
        f"    sage3d.make_env(**{SMALL_ENV!r}, device='gpu')\n"
        "except ValueError as e:\n"
        "    print('refused:', e)\n"
    )
    env = {**os.environ, "SAGE3D_GPU_ADAPTER": "no adapter has this name"}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         check=True).stdout
    assert out.startswith("refused:") and "no GPU adapter" in out, out


def test_gpu_observations_match_the_cpu():
    kw = {"sensors": ALL}
    cpu, gpu = make(**kw), make(**kw, device="gpu")
    assert gpu.render_device.startswith("gpu: "), gpu.render_device
    for env in (cpu, gpu):
        env.action_space.seed(3)
    actions = [1, 2, 1, 3, 1]
    c, _ = cpu.reset(options={"episode_index": 2})
    g, _ = gpu.reset(options={"episode_index": 2})
    assert gpu.observation_space.contains(g)
    assert_close(c, g)
    for a in actions:
        c, rc, tc, uc, _ = cpu.step(a)
        g, rg, tg, ug, _ = gpu.step(a)
        assert (rc, tc, uc) == (rg, tg, ug)
        assert_close(c, g)


def test_gpu_vector_env_matches_single_environments():
    kw = {"sensors": ["rgb", "depth"], "device": "gpu"}
    vec = sage3d.make_vec_env(3, **SMALL_ENV, **kw)
    assert vec.render_device.startswith("gpu: "), vec.render_device
    obs, _ = vec.reset(options={"episode_index": [2, 0, 3]})
    cpu = make(sensors=["rgb", "depth"])
    for i, k in enumerate([2, 0, 3]):
        single, _ = cpu.reset(options={"episode_index": k})
        assert_close(single, {key: v[i] for key, v in obs.items()})
    steps, *_ = vec.step(np.array([1, 2, 3]))
    for i, (k, a) in enumerate(zip([2, 0, 3], [1, 2, 3])):
        cpu.reset(options={"episode_index": k})
        single, *_ = cpu.step(a)
        assert_close(single, {key: v[i] for key, v in steps.items()})
