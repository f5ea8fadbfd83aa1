"""The vector environment: stepping several sub-environments in Rust gives what Gymnasium's
SyncVectorEnv over single environments gives (same seeds, actions and autoresets), and
Gymnasium's vector machinery accepts it."""

import gymnasium
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode, SyncVectorEnv

import sage3d
from conftest import SMALL_ENV

SMALL = {**SMALL_ENV, "width": 24, "height": 16, "max_steps": 4}


pytestmark = pytest.mark.usefixtures("synth_cache")


def test_vector_steps_equal_single_envs_with_next_step_autoreset():
    n = 3
    vec = sage3d.make_vec_env(n, **SMALL)
    assert vec.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    sync = SyncVectorEnv([lambda: sage3d.make_env(**SMALL) for _ in range(n)],
                         autoreset_mode=AutoresetMode.NEXT_STEP)
    assert vec.single_observation_space == sync.single_observation_space
    assert vec.single_action_space == sync.single_action_space
    o1, i1 = vec.reset(seed=11)
    o2, i2 = sync.reset(seed=11)
    rng = np.random.default_rng(0)
    ended = 0
    for step in range(12):
        for k in ("rgb", "depth", "pose"):
            np.testing.assert_array_equal(o1[k], o2[k], err_msg=f"{k} at step {step}")
        assert tuple(o1["instruction"]) == tuple(o2["instruction"])
        assert vec.observation_space.contains(o1)
        actions = rng.integers(0, 4, n)
        o1, r1, t1, u1, i1 = vec.step(actions)
        o2, r2, t2, u2, i2 = sync.step(actions)
        np.testing.assert_array_equal(r1, r2)
        np.testing.assert_array_equal(t1, t2)
        np.testing.assert_array_equal(u1, u2)
        np.testing.assert_array_equal(i1["episode_id"], i2["episode_id"])
        ended += int((t1 | u1).sum())
    assert ended >= n  # every sub-environment went through at least one autoreset


def test_gymnasium_make_vec_uses_the_rust_vector_env():
    env = gymnasium.make_vec("SageVLN-v0", num_envs=2, vectorization_mode="vector_entry_point", **SMALL)
    assert isinstance(env.unwrapped, sage3d.SageVectorEnv)
    obs, infos = env.reset(seed=0)
    assert obs["rgb"].shape == (2, 16, 24, 3)
    obs, r, term, trunc, infos = env.step(np.array([1, 2]))
    assert r.shape == (2,) and infos["step"].tolist() == [1, 1]
    assert not isinstance(obs["rgb"].base, np.ndarray)


def test_wrong_batch_sizes_are_errors():
    vec = sage3d.make_vec_env(2, **SMALL)
    vec.reset(seed=0)
    with pytest.raises(ValueError, match="one per sub-environment"):
        vec.step(np.array([1, 1, 1]))
    # LOOK_UP / LOOK_DOWN are not in MultiDiscrete([4 4]).
    with pytest.raises(ValueError, match="not in the action space MultiDiscrete"):
        vec.step(np.array([4, 5]))
    # An unknown reset option is named with the accepted one, not ignored.
    with pytest.raises(ValueError, match=r"unknown reset option 'episode_id' \(accepted: episode_index\)"):
        vec.reset(options={"episode_id": "x"})
    # Indices and seeds are whole numbers, NumPy's included; others are named.
    for bad, match in (({"episode_index": [0, -1]}, "episode_index: expected a whole number"),
                       ({"episode_index": 0}, "one index per sub-environment")):
        with pytest.raises(ValueError, match=match):
            vec.reset(options=bad)
    # A refused reset reseeds no generator: the episodes drawn after it are those drawn
    # without it.
    def draws(refused):
        vec.reset(seed=7)
        for seed, options in refused:
            with pytest.raises((TypeError, ValueError)):
                vec.reset(seed=seed, options=options)
        return [vec.reset()[0]["pose"].tolist() for _ in range(6)]

    expected = draws([])
    assert draws([(99, {"episode_index": [0, 10**6]}),
                  ([99, 1.5], None),
                  (99, {"episode_index": [0]})]) == expected
    first, _ = vec.reset(seed=np.int64(3))
    again, _ = vec.reset(seed=3)
    np.testing.assert_array_equal(first["pose"], again["pose"])
    # A count no machine holds is named, not tried in an allocation.
    with pytest.raises(ValueError, match="`num_envs` must be 1 to 16384"):
        sage3d.make_vec_env(2**40, **SMALL)
    # Closed, it is not stepped or reset again, as Gymnasium's own vector environments.
    vec.close()
    with pytest.raises(gymnasium.error.ClosedEnvironmentError):
        vec.step(np.array([1, 1]))
    with pytest.raises(gymnasium.error.ClosedEnvironmentError):
        vec.reset(seed=0)


def test_a_step_with_one_refused_action_moves_no_sub_environment():
    vec = sage3d.make_vec_env(2, actions="ground", **{**SMALL, "sensors": []})
    obs, _ = vec.reset(seed=0)
    with pytest.raises(ValueError, match="sub-environment 1"):
        vec.step([[0, 0.3, 0, 0, 0.5], [0, float("nan"), 0, 0, 0.5]])
    obs, *_, info = vec.step([[0, 0, 0, 0, 0.0]] * 2)
    np.testing.assert_array_equal(info["step"], [1, 1])
