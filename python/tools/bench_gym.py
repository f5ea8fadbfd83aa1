"""Steps per second of the Gymnasium environments, the way a training loop drives them.

    python python/tools/bench_gym.py [--steps 400] [--num-envs 4]

One environment (`sage3d.make_env`, the sage preset: RGB + depth at 224x224) and one vector
environment of `--num-envs` sub-environments stepped together in Rust, both on the cached
synthetic home, with uniformly random actions from a fixed seed. Prints steps per second and
the machine's core count.
"""

import argparse
import os
import time

import numpy as np
import sage3d


def rate(step, reset, steps):
    reset()
    step()  # warm the renderer's buffers
    start = time.perf_counter()
    for _ in range(steps):
        step()
    return steps / (time.perf_counter() - start)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=400)
    parser.add_argument("--num-envs", type=int, default=4)
    a = parser.parse_args()
    rng = np.random.default_rng(0)

    env = sage3d.make_env()
    state = {"done": True}

    def one():
        if state["done"]:
            env.reset(seed=int(rng.integers(1 << 30)))
        _, _, term, trunc, _ = env.step(int(rng.integers(1, 4)))
        state["done"] = term or trunc

    single = rate(one, lambda: env.reset(seed=0), a.steps)

    venv = sage3d.make_vec_env(a.num_envs)
    venv.reset(seed=0)

    def many():
        venv.step(rng.integers(1, 4, size=a.num_envs))

    vector = rate(many, lambda: venv.reset(seed=0), a.steps // a.num_envs) * a.num_envs
    print(f"cores            {os.cpu_count()}")
    print(f"single env       {single:.1f} steps/s (RGB + depth 224x224)")
    print(f"vector env x{a.num_envs}    {vector:.1f} steps/s in total")


if __name__ == "__main__":
    main()
