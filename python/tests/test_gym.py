"""The Gymnasium environment of the sage3d package on a small synthetic home: Gymnasium's own
checker, observation types and spaces, zero-copy arrays, determinism by seed, rewards and the
info dict, the registered ids and the continuous action space."""

import json

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import sage3d
from conftest import SMALL_ENV, make_small_env as make

pytestmark = pytest.mark.usefixtures("synth_cache")


def test_gymnasium_env_checker_passes():
    env = make(render_mode="rgb_array", sensors=["rgb", "depth", "semantic", "instance"])
    check_env(env, skip_render_check=False)


def test_observations_are_typed_arrays_in_the_space_that_own_the_rust_buffers():
    env = make(sensors=["rgb", "depth", "semantic", "instance"], config={"sensors": {"depth_size": [16, 12]}})
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    assert obs["rgb"].shape == (24, 32, 3) and obs["rgb"].dtype == np.uint8
    assert obs["depth"].shape == (12, 16) and obs["depth"].dtype == np.float32
    assert obs["semantic"].shape == (24, 32) and obs["semantic"].dtype == np.uint16
    assert obs["instance"].shape == (24, 32) and obs["instance"].dtype == np.uint32
    assert obs["pose"].dtype == np.float32 and obs["pose"].shape == (4,)
    assert isinstance(obs["instruction"], str) and obs["instruction"]
    for key in ("rgb", "depth", "semantic", "instance"):
        a = obs[key]
        # Not a copy: NumPy does not own the memory, and its base is the Rust container
        # (an ndarray base would mean NumPy made a view of its own copy).
        assert not a.flags.owndata and a.base is not None and not isinstance(a.base, np.ndarray)
        assert a.flags.c_contiguous and a.flags.writeable
    # The camera sees something: depth hits within the far plane, several colours.
    assert (obs["depth"] > 0).any() and obs["depth"].max() <= 100
    assert len(np.unique(obs["rgb"].reshape(-1, 3), axis=0)) > 4
    np.testing.assert_allclose(obs["pose"], info["pose"], rtol=1e-6)


def rollout(env, seed, steps=12):
    obs, info = env.reset(seed=seed)
    env.action_space.seed(seed)
    out = [(obs, 0.0, False, False, info)]
    for _ in range(steps):
        a = env.action_space.sample()
        obs, r, term, trunc, info = env.step(a)
        out.append((obs, r, term, trunc, info))
        if term or trunc:
            obs, info = env.reset()
            out.append((obs, 0.0, False, False, info))
    return out


def same(a, b):
    for (o1, r1, t1, u1, i1), (o2, r2, t2, u2, i2) in zip(a, b, strict=True):
        assert o1.keys() == o2.keys()
        for k in o1:
            np.testing.assert_array_equal(o1[k], o2[k])
        assert (r1, t1, u1) == (r2, t2, u2)
        assert i1 == i2


def test_same_seed_same_episodes_observations_rewards_and_infos():
    a = rollout(make(), seed=7)
    same(a, rollout(make(), seed=7))
    other = rollout(make(), seed=8)
    assert any(x[4]["episode_id"] != y[4]["episode_id"] or not np.array_equal(x[0]["rgb"], y[0]["rgb"])
               for x, y in zip(a, other, strict=False))


def test_info_has_pose_contacts_metrics_so_far_and_final_metrics():
    env = make(task="vln")
    obs, info = env.reset(seed=0)
    assert info["contacts"] == [] and info["step"] == 0 and "metrics" not in info
    d0 = info["metrics_so_far"]["distance_to_goal"]
    assert d0 > 0
    start = np.array(info["pose"][:2])
    total = 0.0
    for _ in range(3):
        obs, r, term, trunc, info = env.step(1)  # FORWARD
        total += r
        assert not term and not trunc
    moved = np.linalg.norm(np.array(info["pose"][:2]) - start)
    assert info["metrics_so_far"]["steps"] == 3
    assert info["metrics_so_far"]["path_length"] == pytest.approx(moved, abs=1e-4)
    assert info["step_info"]["action"] == {"type": "move_forward"}
    assert all({"instance", "distance"} <= set(c) for c in info["contacts"])
    obs, r, term, trunc, info = env.step(0)  # STOP
    assert term and not trunc and info["termination"] == "stop"
    m = info["metrics"]
    assert set(m) >= {"sr", "spl", "ne", "tl"} and m["tl"] == pytest.approx(moved, abs=1e-3)
    # VLN reward: progress towards the goal region (Euclidean) minus 0.01 per step, plus 2.5 on
    # a successful STOP.
    success = 2.5 if info["within_success_distance"] else 0.0
    final = info["step_info"]["distance_to_goal"]
    assert total + r == pytest.approx(d0 - final - 4 * 0.01 + success, abs=1e-4)
    with pytest.raises(ValueError, match="reset first"):
        env.step(1)


def test_registered_ids_and_tasks():
    env = gymnasium.make("SageNoGoal-v0", **SMALL_ENV)
    assert {e["task"] for e in env.unwrapped.episodes} == {"nogoal"}
    obs, _ = env.reset(seed=0)
    assert "avoid colliding" in obs["instruction"]
    # NoGoal pays the metres moved (less the slack): forward in free space pays about 0.24.
    _, r, *_ = env.step(1)
    assert -0.02 < r <= 0.25 - 0.01 + 1e-6
    vln = gymnasium.make("SageVLN-v0", **SMALL_ENV)
    assert {e["task"] for e in vln.unwrapped.episodes} == {"vln"}
    assert vln.action_space == gymnasium.spaces.Discrete(4)
    assert make(look=True).action_space == gymnasium.spaces.Discrete(6)


def test_episode_options_and_render():
    env = make(render_mode="rgb_array")
    target = env.episodes[2]
    obs, info = env.reset(options={"episode_id": target["episode_id"]})
    assert info["episode_id"] == target["episode_id"] and obs["instruction"] == target["instruction"]
    np.testing.assert_allclose(obs["pose"][:3], target["start"]["position"], atol=1e-5)
    frame = env.render()
    assert frame.shape == (24, 32, 3) and frame.dtype == np.uint8
    np.testing.assert_array_equal(frame, obs["rgb"])
    with pytest.raises(ValueError, match="not among"):
        env.reset(options={"episode_id": "nope"})


def test_sensor_names_as_text_may_have_spaces():
    # As the command line's --sensors reads them: spaces around a name and empty names are
    # dropped; an unknown name is still an error naming it.
    spaced = make(sensors="rgb, depth")
    listed = make(sensors=[" rgb", "depth "])
    plain = make(sensors=["rgb", "depth"])
    assert set(spaced.observation_space.spaces) == set(plain.observation_space.spaces)
    assert set(listed.observation_space.spaces) == set(plain.observation_space.spaces)
    assert {"rgb", "depth"} <= set(spaced.observation_space.spaces)
    assert "semantic" not in spaced.observation_space.spaces
    with pytest.raises(ValueError, match=r"unknown sensors \['lidar'\]"):
        make(sensors="rgb, lidar")
    # With render_mode="rgb_array", text names are names, not letters: rgb is added.
    depth = make(render_mode="rgb_array", sensors="depth")
    assert {"rgb", "depth"} <= set(depth.observation_space.spaces)


def test_continuous_ground_actions():
    env = make(actions="ground", sensors=[])
    assert env.action_space.shape == (5,)
    assert set(env.observation_space.spaces) == {"pose", "instruction"}
    obs, info = env.reset(seed=3)
    start, yaw = obs["pose"][:2].copy(), obs["pose"][3]
    obs, r, term, trunc, info = env.step(np.array([0.0, 0.5, 0.0, 0.0, 0.4], np.float32))
    moved = np.linalg.norm(obs["pose"][:2] - start)
    assert moved == pytest.approx(info["step_info"]["achieved"], abs=1e-3)
    assert info["step_info"]["commanded"] == pytest.approx(0.2, abs=1e-5)
    assert info["time"] == pytest.approx(0.4)
    assert obs["pose"][3] == pytest.approx(yaw, abs=1e-5)
    obs, r, term, trunc, info = env.step([1.0, 0, 0, 0, 0])
    assert term and info["termination"] == "stop"
    env.reset(seed=0)
    with pytest.raises(ValueError, match="5 numbers"):
        env.step([0.0, 1.0])
    # Closed, it frees what it holds and is not stepped or reset again.
    env.close()
    env.close()
    with pytest.raises(gymnasium.error.ClosedEnvironmentError):
        env.step([1.0, 0, 0, 0, 0])
    with pytest.raises(gymnasium.error.ClosedEnvironmentError):
        env.reset(seed=0)


def test_uav_action_box_ends_where_the_physics_clamps():
    env = make(actions="uav", sensors=[])
    profile = sage3d.env_config("sage", json.dumps({"agent": "uav"}))["profile"]
    assert env.action_space.shape == (6,)
    # vz is bounded by the climb rate, not the speed: the box's edge is where the physics
    # stops answering a larger command.
    assert env.action_space.high[3] == pytest.approx(profile["max_climb"])
    assert profile["max_climb"] < profile["max_speed"]

    def rise(vz):
        obs, _ = env.reset(seed=3, options={"episode_index": 0})
        z = obs["pose"][2]
        obs, *_ = env.step(np.array([0.0, 0.0, 0.0, vz, 0.0, 0.2], np.float32))
        return obs["pose"][2] - z

    edge = float(env.action_space.high[3])
    assert rise(edge) == pytest.approx(edge * 0.2, abs=1e-4)
    assert rise(edge * 2) == pytest.approx(rise(edge), abs=1e-6)
    assert rise(edge / 2) == pytest.approx(edge * 0.1, abs=1e-4)


def test_bad_settings_are_clear_errors():
    with pytest.raises(ValueError, match="hfov"):
        make(hfov=190)
    with pytest.raises(ValueError, match="`sensors.hfov_deg`: expected a finite number, got nan"):
        make(hfov=float("nan"))
    with pytest.raises(ValueError, match="unknown sensors"):
        make(sensors=["lidar"])
    env = make()
    env.reset(seed=0)
    # LOOK_UP (4) is not among Discrete(4)'s actions: refused, as any index past the space.
    for action in (9, 4, -1, 1.5):
        with pytest.raises(ValueError, match=r"not in the action space Discrete\(4\)"):
            env.step(action)
    looking = make(look=True)
    looking.reset(seed=0)
    looking.step(4)
    for bad, match in (({"episode_index": -1}, "episode_index: expected a whole number"),
                       ({"episode_index": 10**6}, "episode_index: 1000000 is past")):
        with pytest.raises(ValueError, match=match):
            env.reset(options=bad)
    # A misspelt or unknown reset option is named with the accepted ones, not ignored (the
    # episode would be drawn at random instead of the one asked for); nothing is reseeded.
    env.reset(seed=5)
    drawn = env.np_random.integers(1000)
    env.reset(seed=5)
    for bad, match in (({"foo": 1}, r"unknown reset option 'foo' \(accepted: episode_id, episode_index\)"),
                       ({"episode": "x", "seed": 3}, r"unknown reset option 'episode', 'seed'"),
                       ({"episode_id": env.episodes[0]["episode_id"], "episode_index": 1},
                        "not both"),
                       ({"episode_id": "no such episode"}, "is not among this env's episodes"),
                       ({"episode_index": 10**6}, "episode_index: 1000000 is past")):
        with pytest.raises(ValueError, match=match):
            env.reset(seed=99, options=bad)
    assert env.np_random.integers(1000) == drawn
    env.reset(seed=5)
    with pytest.raises(TypeError, match="seed: expected a whole number"):
        env.reset(seed=1.5)
    assert env.np_random.integers(1000) == drawn
    with pytest.raises(TypeError, match="expected a dict"):
        env.reset(options=["episode_id"])
    with pytest.raises(ValueError, match="num_episodes: expected a whole number >= 1"):
        make(num_episodes=-1)
    # Sizes and counts are whole numbers, named when not (never truncated, never an
    # OverflowError that names nothing).
    for bad, error, match in (({"width": 1.5}, TypeError, "width: expected a whole number"),
                              ({"seed": "1"}, TypeError, "seed: expected a whole number"),
                              ({"height": 0}, ValueError, "height: expected a whole number >= 1"),
                              ({"max_steps": -3}, ValueError, "max_steps: expected")):
        with pytest.raises(error, match=match):
            make(**bad)
    with pytest.raises(TypeError, match="seed: expected a whole number"):
        env.reset(seed="1")
    for bad in ({"seed": -1}, {"rooms": -2}, {"gaussians": 0}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            sage3d.synth_scene(**bad)
    # Rendering shows the rgb sensor: a config that turns it off is refused when the env is made.
    with pytest.raises(ValueError, match="render_mode='rgb_array'"):
        make(render_mode="rgb_array", config={"sensors": {"rgb": False}})
    # A misspelt field of `config` is named, not ignored.
    with pytest.raises(ValueError, match="sensors.widht: unknown field"):
        make(config={"sensors": {"widht": 3}})


def test_splat_bodies_choose_the_bodies_the_scenes_are_loaded_with():
    env = make(config={"splat_bodies": "never"})
    assert env.config["splat_bodies"] == "never"
    assert [s.splat_bodies for s in env.scenes] == ["never"]
    env.reset(seed=0)
    # The default is left out of the resolved config, as before the choice existed.
    assert "splat_bodies" not in make().config
    scene = sage3d.Scene.load(make().scenes[0].path)
    assert scene.splat_bodies == "auto"
    # A scene loaded with other bodies than the config asks for is refused, naming both.
    with pytest.raises(ValueError, match="splat_bodies.*'never'.*'auto'"):
        make(scene=scene, config={"splat_bodies": "never"})
    with pytest.raises(ValueError, match="splat_bodies.*sometimes"):
        sage3d.Scene.load(scene.path, splat_bodies="sometimes")
    with pytest.raises(ValueError, match="splat_bodies"):
        sage3d.evaluate("unused", agent="oracle", out="unused-run", config={"splat_bodies": "never"})
