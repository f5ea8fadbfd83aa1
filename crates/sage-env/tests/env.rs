//! The environment on a small synthetic scene: observations, actions, termination, the oracle's
//! success, determinism across runs and thread counts, vector environments, and rendering on
//! the GPU.

use sage_core::Pose;
use sage_env::agents::{Agent, ForwardAgent, OracleAgent, RandomAgent, run_episode};
use sage_env::{
    Action, ActionSpace, Env, EnvConfig, EnvEpisode, SceneContext, SensorConfig, Termination,
};
use sage_nav::TrajectoryParams;
use sage_physics::{Decomposer, HullCache, SceneBodies};
use sage_splat::Device;
use sage_synth::{SceneKind, SynthConfig, generate};
use std::sync::{Arc, OnceLock};

struct Fixture {
    ctx: Arc<SceneContext>,
    /// The scene's bodies, for contexts of a test's own.
    bodies: SceneBodies,
    episodes: Vec<EnvEpisode>,
}

/// A 3-room home with box bodies (meshes dropped: the box is then the body, which keeps the
/// test fast) and six planned trajectories as VLN episodes.
fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let mut scene = generate(&SynthConfig {
            seed: 7,
            kind: SceneKind::Home,
            rooms: 3,
            objects: 24,
            gaussians: 3000,
            ..SynthConfig::default()
        })
        .unwrap();
        for o in &mut scene.objects {
            o.mesh = None;
        }
        let cache = tempfile::tempdir().unwrap();
        let (bodies, _) = SceneBodies::build(
            &scene,
            &Decomposer::default(),
            &HullCache::new(cache.path()),
        )
        .unwrap();
        let params = TrajectoryParams {
            count: 6,
            seed: 3,
            ..TrajectoryParams::default()
        };
        let prep = sage_nav::trajectory::prepare(&scene, &params).unwrap();
        let (set, _) = sage_nav::trajectory::generate(&scene.name, &prep, &params).unwrap();
        let episodes: Vec<EnvEpisode> = set
            .trajectories
            .iter()
            .map(|t| EnvEpisode::from_trajectory(format!("t{}", t.id), t, "go to the goal"))
            .collect();
        assert!(episodes.len() >= 4, "{} trajectories", episodes.len());
        let ctx =
            SceneContext::new(scene, bodies.clone(), &params.grid, params.cost.clone()).unwrap();
        Fixture {
            ctx: Arc::new(ctx),
            bodies,
            episodes,
        }
    })
}

fn blind() -> EnvConfig {
    EnvConfig {
        sensors: SensorConfig {
            rgb: false,
            depth: false,
            ..SensorConfig::default()
        },
        ..EnvConfig::default()
    }
}

fn tiny_camera() -> EnvConfig {
    EnvConfig {
        sensors: SensorConfig {
            width: 16,
            height: 12,
            depth_size: Some([8, 6]),
            semantic: true,
            ..SensorConfig::default()
        },
        ..EnvConfig::default()
    }
}

#[test]
fn oracle_reaches_every_reachable_goal() {
    let f = fixture();
    let mut env = Env::new(f.ctx.clone(), blind()).unwrap();
    let mut oracle = OracleAgent::new(0.25);
    for e in &f.episodes {
        let trace = run_episode(&mut env, &mut oracle, e).unwrap();
        let last = trace.steps.last().unwrap();
        assert!(trace.stop_called(), "{}: {:?}", e.id, trace.termination);
        let d = last.distance_to_goal.unwrap();
        assert!(d <= 1.0, "{}: ended {d} m from the goal region", e.id);
        // The geodesic inputs of the metrics are filled in at the end.
        let g = &trace.geodesics;
        assert!(g.start_to_region.is_some() && g.start_to_point.is_some());
        assert_eq!(g.steps_to_point.len(), trace.steps.len());
        assert!(g.final_to_region.unwrap() <= 1.0 + 1e-3);
        assert!(env.within_success_distance());
    }
    // An end point at the edge of the success distance: the oracle closes in on the footprint
    // instead of stopping just outside it.
    let mut edge_cases = 0;
    for e in f
        .episodes
        .iter()
        .filter(|e| e.goal.as_ref().unwrap().object.is_some())
    {
        let goal = e.goal.as_ref().unwrap();
        let region = f.ctx.footprint(goal.object.as_ref().unwrap()).unwrap();
        let end = goal.point.truncate();
        let near = region.nearest_boundary_point(end).unwrap();
        let out = near + (end - near).normalize() * 1.12;
        if !f.ctx.pathfinder.is_navigable(out) || region.distance_to_boundary(out) < 1.1 {
            continue;
        }
        let mut moved = e.clone();
        moved.goal.as_mut().unwrap().point = out.extend(0.0);
        let trace = run_episode(&mut env, &mut oracle, &moved).unwrap();
        assert!(trace.stop_called(), "{}", e.id);
        assert!(env.within_success_distance(), "{}: stopped outside", e.id);
        edge_cases += 1;
    }
    assert!(
        edge_cases > 0,
        "no object goal with room behind its end point"
    );
    // A goal outside the scene cannot be planned to: the oracle stops at once.
    let mut far = f.episodes[0].clone();
    far.goal.as_mut().unwrap().point = glam::Vec3::new(1e3, 1e3, 0.0);
    far.goal.as_mut().unwrap().object = None;
    let trace = run_episode(&mut env, &mut oracle, &far).unwrap();
    assert_eq!(trace.steps.len(), 1);
    assert!(trace.stop_called() && !env.within_success_distance());
    assert_eq!(trace.geodesics.final_to_region, None);
}

#[test]
fn observations_follow_the_sensor_config() {
    let f = fixture();
    let mut env = Env::new(f.ctx.clone(), tiny_camera()).unwrap();
    let e = &f.episodes[0];
    let obs = env.reset(e).unwrap();
    assert_eq!(obs.pose, e.start);
    assert_eq!(&*obs.instruction, "go to the goal");
    assert_eq!((obs.step, obs.time), (0, 0.0));
    let im = obs.images.unwrap();
    assert_eq!((im.width, im.height), (16, 12));
    assert_eq!(im.rgb.as_ref().unwrap().len(), 16 * 12 * 3);
    assert_eq!(im.depth_size, (8, 6));
    assert_eq!(im.depth.as_ref().unwrap().len(), 8 * 6);
    assert_eq!(im.semantic.as_ref().unwrap().len(), 16 * 12);
    assert!(im.instance.is_none());
    // Inside a furnished home something is in view.
    assert!(im.depth.unwrap().iter().any(|&d| d > 0.0));
    // Looking up tilts the camera one step, clamped at 60°.
    let mut pitch = 0.0;
    for _ in 0..3 {
        pitch = env.step(Action::LookUp).unwrap().0.pitch;
    }
    assert!((pitch - 60f32.to_radians()).abs() < 1e-6);
    assert_eq!(env.pose().unwrap(), e.start);
    let (obs, info) = env.step(Action::TurnLeft).unwrap();
    assert!((obs.pose.yaw - sage_core::wrap_angle(e.start.yaw + 15f32.to_radians())).abs() < 1e-5);
    assert_eq!(info.time, 4.0);
}

#[test]
fn termination_rules() {
    let f = fixture();
    let mut cfg = blind();
    cfg.task.max_steps = 5;
    let mut env = Env::new(f.ctx.clone(), cfg.clone()).unwrap();
    let e = &f.episodes[1];
    let trace = run_episode(&mut env, &mut ForwardAgent::new(None), e).unwrap();
    assert_eq!(trace.steps.len(), 5);
    assert_eq!(trace.termination, Some(Termination::MaxSteps));
    assert!(env.step(Action::MoveForward).is_err());
    // Pressed against whatever it faces, the agent still gets finite geodesic distances.
    let mut long = cfg.clone();
    long.task.max_steps = 40;
    let mut env40 = Env::new(f.ctx.clone(), long).unwrap();
    let trace = run_episode(&mut env40, &mut ForwardAgent::new(None), &f.episodes[0]).unwrap();
    assert!(trace.steps.iter().any(|s| s.intensity > 0.5));
    assert!(trace.geodesics.final_to_region.is_some());
    assert!(trace.geodesics.steps_to_point.iter().all(Option::is_some));
    // STOP ends at once and counts as a step.
    let trace = run_episode(&mut env, &mut ForwardAgent::new(Some(2)), e).unwrap();
    assert_eq!(trace.steps.len(), 3);
    assert!(trace.stop_called());
    // NoGoal: forward until the first collision or the time limit.
    let nogoal = EnvEpisode {
        task: sage_core::Task::Nogoal,
        goal: None,
        ..e.clone()
    };
    cfg.task.max_steps = 500;
    let mut env = Env::new(f.ctx.clone(), cfg.clone()).unwrap();
    let trace = run_episode(&mut env, &mut ForwardAgent::new(None), &nogoal).unwrap();
    let last = trace.steps.last().unwrap();
    assert_eq!(trace.termination, Some(Termination::Collision));
    assert!(
        last.collision
            && trace.steps[..trace.steps.len() - 1]
                .iter()
                .all(|s| !s.collision)
    );
    assert_eq!(last.time, trace.steps.len() as f32);
    cfg.task.nogoal_time_limit = 3.0;
    let mut env = Env::new(f.ctx.clone(), cfg).unwrap();
    let mut turner = RandomAgent::new(1, 0.0).unwrap();
    let trace = run_episode(&mut env, &mut turner, &nogoal).unwrap();
    assert!(trace.steps.len() <= 3);
    // A VLN episode needs a goal.
    let bad = EnvEpisode {
        goal: None,
        ..e.clone()
    };
    assert!(
        env.reset(&bad)
            .unwrap_err()
            .message()
            .contains("needs a goal")
    );
}

#[test]
fn action_spaces() {
    let f = fixture();
    let e = &f.episodes[0];
    let mut env = Env::new(f.ctx.clone(), blind()).unwrap();
    env.reset(e).unwrap();
    let v = Action::Velocity {
        vx: 0.2,
        vy: 0.0,
        wz: 0.0,
        dt: 0.5,
    };
    assert!(env.step(v).unwrap_err().message().contains("discrete"));
    let mut cfg = blind();
    cfg.actions = ActionSpace::Ground { max_dt: 1.0 };
    let mut env = Env::new(f.ctx.clone(), cfg.clone()).unwrap();
    env.reset(e).unwrap();
    let spin = Action::Velocity {
        vx: 0.0,
        vy: 0.0,
        wz: 0.4,
        dt: 0.5,
    };
    let (obs, info) = env.step(spin).unwrap();
    assert_eq!(info.time, 0.5);
    assert!((obs.pose.yaw - sage_core::wrap_angle(e.start.yaw + 0.2)).abs() < 1e-5);
    assert_eq!(obs.pose.position, e.start.position);
    let long = Action::Velocity {
        vx: 0.1,
        vy: 0.0,
        wz: 0.0,
        dt: 2.0,
    };
    assert!(env.step(long).is_err());
    assert!(env.step(Action::MoveForward).is_err());
    // The baselines refuse a continuous space.
    assert!(OracleAgent::new(0.25).reset(&env, e).is_err());
    // The UAV space needs the UAV profile.
    cfg.actions = ActionSpace::Uav { max_dt: 1.0 };
    assert!(Env::new(f.ctx.clone(), cfg.clone()).is_err());
    cfg.agent = "uav".into();
    let mut env = Env::new(f.ctx.clone(), cfg).unwrap();
    let start = EnvEpisode {
        start: Pose::new(e.start.position + glam::Vec3::Z * 1.0, e.start.yaw),
        ..e.clone()
    };
    env.reset(&start).unwrap();
    let up = Action::Fly {
        vx: 0.0,
        vy: 0.0,
        vz: 0.5,
        wz: 0.0,
        dt: 1.0,
    };
    let (obs, _) = env.step(up).unwrap();
    assert!((obs.pose.position.z - (start.start.position.z + 0.5)).abs() < 1e-4);
}

#[test]
fn displacements_are_one_step_through_physics() {
    let f = fixture();
    let e = &f.episodes[0];
    let mut env = Env::new(f.ctx.clone(), blind()).unwrap();
    // Forward-only displacements follow exactly the path of FORWARD steps, blocked by the
    // same bodies (slid along, never passed through).
    let forward = Action::Displace {
        dx: 0.25,
        dy: 0.0,
        dyaw: 0.0,
    };
    let mut walked = Vec::new();
    for action in [Action::MoveForward, forward] {
        env.reset(e).unwrap();
        let mut poses = Vec::new();
        while !env.done() && poses.len() < 60 {
            let (_, info) = env.step(action).unwrap();
            poses.push((info.pose, info.collision, info.time));
        }
        walked.push(poses);
    }
    assert_eq!(walked[0].len(), walked[1].len());
    for (a, b) in walked[0].iter().zip(&walked[1]) {
        assert!(a.0.position.distance(b.0.position) < 1e-5, "{a:?} {b:?}");
        assert_eq!((a.1, a.2), (b.1, b.2));
    }
    assert!(
        walked[1].iter().any(|p| p.1),
        "the walk never touched anything"
    );
    // Sideways and a turn: (dx, dy) in the body frame at the start heading, then the turn.
    env.reset(e).unwrap();
    let (dx, dy, dyaw) = (0.1f32, 0.05f32, 0.3f32);
    let (obs, info) = env.step(Action::Displace { dx, dy, dyaw }).unwrap();
    let (s, c) = e.start.yaw.sin_cos();
    let want = e.start.position.truncate() + glam::Vec2::new(c * dx - s * dy, s * dx + c * dy);
    assert!(!info.collision);
    assert!(obs.pose.position.truncate().distance(want) < 1e-4);
    assert!((obs.pose.yaw - sage_core::wrap_angle(e.start.yaw + dyaw)).abs() < 1e-5);
    assert_eq!(info.time, 1.0);
    // The profile's speed limit (the wheeled robot: 1 m/s over the 1 s step) caps a long row.
    env.reset(e).unwrap();
    let (obs, _) = env
        .step(Action::Displace {
            dx: 3.0,
            dy: 0.0,
            dyaw: 0.0,
        })
        .unwrap();
    assert!(obs.pose.position.distance(e.start.position) <= 1.0 + 1e-4);
    // So it does a row beyond what any command may ask (a server's 20 km, 10³⁰ rad): as far as
    // the limits allow, as the 3 m row.
    let far = obs.pose;
    for (dx, dyaw) in [(20_000.0, 0.0), (1e30, 0.0)] {
        env.reset(e).unwrap();
        let (obs, _) = env.step(Action::Displace { dx, dy: 0.0, dyaw }).unwrap();
        assert!(obs.pose.position.distance(far.position) < 1e-4, "{dx}");
    }
    env.reset(e).unwrap();
    for (dx, dy, dyaw) in [(0.0, -1e30, 1e30), (1e30, 1e30, 1e30), (3e38, -3e38, -3e38)] {
        env.reset(e).unwrap();
        env.step(Action::Displace { dx, dy, dyaw }).unwrap();
    }
    let bad = Action::Displace {
        dx: f32::NAN,
        dy: 0.0,
        dyaw: 0.0,
    };
    assert!(env.step(bad).unwrap_err().message().contains("finite"));
    // Only the discrete space takes displacements.
    let mut cfg = blind();
    cfg.actions = ActionSpace::Ground { max_dt: 1.0 };
    let mut env = Env::new(f.ctx.clone(), cfg).unwrap();
    env.reset(e).unwrap();
    assert!(env.step(forward).unwrap_err().message().contains("ground"));
}

/// Runs every episode with a seeded random agent, rendering, and returns traces and images.
fn rollout(threads: usize) -> Vec<(String, Vec<u8>)> {
    let f = fixture();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        let mut env = Env::new(f.ctx.clone(), tiny_camera()).unwrap();
        let mut agent = RandomAgent::new(11, 0.05).unwrap();
        f.episodes
            .iter()
            .map(|e| {
                let mut obs = env.reset(e).unwrap();
                agent.reset(&env, e).unwrap();
                let mut pixels = Vec::new();
                while !env.done() && obs.step < 12 {
                    obs = env.step(agent.act(&obs).unwrap()).unwrap().0;
                    pixels.extend(obs.images.as_ref().unwrap().rgb.as_ref().unwrap());
                }
                let trace = env.trace().unwrap();
                (format!("{:?}", trace.steps), pixels)
            })
            .collect()
    })
}

#[test]
fn an_episode_does_not_depend_on_the_one_before() {
    let f = fixture();
    let run = |env: &mut Env, e: &EnvEpisode| {
        let mut agent = RandomAgent::new(5, 0.0).unwrap();
        run_episode(env, &mut agent, e).unwrap().steps
    };
    let mut cfg = blind();
    cfg.task.max_steps = 60;
    let mut used = Env::new(f.ctx.clone(), cfg.clone()).unwrap();
    run(&mut used, &f.episodes[1]);
    let after = run(&mut used, &f.episodes[2]);
    let mut fresh = Env::new(f.ctx.clone(), cfg).unwrap();
    assert_eq!(after, run(&mut fresh, &f.episodes[2]));
}

#[test]
fn same_inputs_same_observations_any_thread_count() {
    let a = rollout(1);
    assert_eq!(a, rollout(3));
    // The random agent really varies between episodes.
    assert!(a.windows(2).any(|w| w[0].0 != w[1].0));
}

/// The pooled environment: rewards sum to the progress towards the goal region minus the slack
/// per step (plus the success reward when the oracle stops inside it), the oracle's STOP is
/// `terminated`, info holds the metrics once the episode ended, and a vector of pooled
/// environments gives, sub-environment for sub-environment, the transitions of single ones.
#[test]
fn pooled_environments_pay_habitat_rewards_and_vector_ones_equal_single_ones() {
    use sage_env::pool::Order;
    use sage_env::reward::{SLACK, SUCCESS_REWARD};
    use sage_env::{Pool, PoolEpisode, PooledEnv, VecEnv};
    use sage_metrics::Mode;
    let f = fixture();
    let entries: Vec<PoolEpisode> = f
        .episodes
        .iter()
        .map(|e| PoolEpisode {
            scene: 0,
            scene_name: "home".into(),
            episode: e.clone(),
        })
        .collect();
    let pool = Arc::new(Pool::new(vec![f.ctx.clone()], entries).unwrap());
    assert!(Pool::new(vec![], vec![]).is_err());
    let mut env = PooledEnv::new(pool.clone(), blind(), Mode::Sage);
    assert!(env.step(Action::MoveForward).is_err(), "step before reset");
    let start = env.reset(0).unwrap();
    assert_eq!(
        (start.reward, start.terminated, start.truncated),
        (0.0, false, false)
    );
    assert!(start.info.metrics.is_none());
    let d0 = start.info.metrics_so_far.distance_to_goal.unwrap();
    let mut oracle = OracleAgent::new(0.25);
    let mut inner = Env::new(f.ctx.clone(), blind()).unwrap();
    let mut obs = inner.reset(&f.episodes[0]).unwrap();
    oracle.reset(&inner, &f.episodes[0]).unwrap();
    let (mut total, mut steps) = (0.0f32, 0usize);
    let last = loop {
        let action = oracle.act(&obs).unwrap();
        let (o, _) = inner.step(action).unwrap();
        obs = o;
        let t = env.step(action).unwrap();
        total += t.reward;
        steps += 1;
        if t.terminated || t.truncated {
            break t;
        }
    };
    assert!(last.terminated && !last.truncated);
    assert_eq!(last.info.termination, Some(Termination::Stop));
    let metrics = last.info.metrics.as_ref().unwrap();
    assert_eq!(metrics.sr, Some(1.0));
    let d_end = last.info.metrics_so_far.distance_to_goal.unwrap();
    let want = d0 - d_end - SLACK * steps as f32 + SUCCESS_REWARD;
    assert!((total - want).abs() < 1e-3, "{total} vs {want}");

    let mut vec_env = VecEnv::new(2, pool.clone(), blind(), Mode::Sage).unwrap();
    assert!(VecEnv::new(0, pool.clone(), blind(), Mode::Sage).is_err());
    // A count no machine holds is refused, not tried in an allocation.
    let e = VecEnv::new(1 << 40, pool.clone(), blind(), Mode::Sage)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("`num_envs` must be 1 to 16384"), "{e}");
    assert!(
        vec_env.run(vec![Order::Reset(0)]).is_err(),
        "one order per env"
    );
    let batch = vec_env.run(vec![Order::Reset(0), Order::Reset(1)]).unwrap();
    let step = vec_env
        .run(vec![
            Order::Step(Action::MoveForward),
            Order::Step(Action::TurnLeft),
        ])
        .unwrap();
    // A batch with one action the space refuses changes no sub-environment: the one before
    // it is not stepped either.
    let nan = Action::Displace {
        dx: f32::NAN,
        dy: 0.0,
        dyaw: 0.0,
    };
    let e = vec_env
        .run(vec![Order::Step(Action::MoveForward), Order::Step(nan)])
        .unwrap_err()
        .to_string();
    assert!(e.contains("sub-environment 1"), "{e}");
    let again = vec_env
        .run(vec![
            Order::Step(Action::TurnLeft),
            Order::Step(Action::TurnLeft),
        ])
        .unwrap();
    assert_eq!(
        again[0].info.step,
        step[0].info.step + 1,
        "not stepped twice"
    );
    assert_eq!(again[0].info.pose[..3], step[0].info.pose[..3]);
    for (i, action) in [Action::MoveForward, Action::TurnLeft]
        .into_iter()
        .enumerate()
    {
        let mut single = PooledEnv::new(pool.clone(), blind(), Mode::Sage);
        let r = single.reset(i).unwrap();
        assert_eq!(r.info.pose, batch[i].info.pose);
        let s = single.step(action).unwrap();
        assert_eq!(
            (s.reward, s.info.pose, s.info.step),
            (step[i].reward, step[i].info.pose, step[i].info.step)
        );
    }
}

/// The images of a vector environment equal those of single environments, sub-environment
/// for sub-environment and in order, when sub-environments share scenes (two pool scenes over
/// one context, so rendering groups by scene index while sharing one upload) and some have
/// no camera change.
#[test]
fn vector_observations_equal_single_ones_with_images() {
    use sage_env::pool::Order;
    use sage_env::{Pool, PoolEpisode, PooledEnv, VecEnv};
    use sage_metrics::Mode;
    let f = fixture();
    let entries: Vec<PoolEpisode> = f
        .episodes
        .iter()
        .take(4)
        .enumerate()
        .map(|(i, e)| PoolEpisode {
            scene: i % 2,
            scene_name: format!("home{}", i % 2),
            episode: e.clone(),
        })
        .collect();
    let pool = Arc::new(Pool::new(vec![f.ctx.clone(), f.ctx.clone()], entries).unwrap());
    let mut vec_env = VecEnv::new(4, pool.clone(), tiny_camera(), Mode::Sage).unwrap();
    assert!(
        vec_env
            .open(1)
            .unwrap()
            .render_device()
            .unwrap()
            .starts_with("cpu")
    );
    let resets: Vec<Order> = (0..4).map(|i| Order::Reset(3 - i)).collect();
    let actions = [
        Action::MoveForward,
        Action::TurnLeft,
        Action::LookUp,
        Action::Stop,
    ];
    let batch = vec_env.run(resets).unwrap();
    let steps = vec_env
        .run(actions.iter().map(|&a| Order::Step(a)).collect())
        .unwrap();
    // A finished sub-environment resets beside the others stepping.
    let mixed = vec_env
        .run(vec![
            Order::Step(Action::TurnRight),
            Order::Step(Action::MoveForward),
            Order::Step(Action::LookDown),
            Order::Reset(0),
        ])
        .unwrap();
    for i in 0..4 {
        let mut single = PooledEnv::new(pool.clone(), tiny_camera(), Mode::Sage);
        let r = single.reset(3 - i).unwrap();
        assert_eq!(r.obs, batch[i].obs, "reset of sub-environment {i}");
        assert_eq!(r.info.episode_index, batch[i].info.episode_index);
        let s = single.step(actions[i]).unwrap();
        assert_eq!(s.obs, steps[i].obs, "step of sub-environment {i}");
        assert_eq!(s.reward, steps[i].reward);
        let m = if i == 3 {
            single.reset(0).unwrap()
        } else {
            single
                .step([Action::TurnRight, Action::MoveForward, Action::LookDown][i])
                .unwrap()
        };
        assert_eq!(m.obs, mixed[i].obs, "third order of sub-environment {i}");
        assert_eq!(m.info.step, mixed[i].info.step);
    }
    assert!(batch[0].obs.images.as_ref().unwrap().rgb.is_some());
}

/// `gpu` opens on any adapter (Mesa's software one where there is no GPU) and every
/// environment over a scene renders from one upload of it; `auto` takes only a hardware GPU,
/// falling back to the CPU with the reason.
/// A context over the fixture's scene that no other test's environments render through.
fn own_context(f: &Fixture) -> Arc<SceneContext> {
    Arc::new(
        SceneContext::new(
            f.ctx.scene.clone(),
            f.bodies.clone(),
            &TrajectoryParams::default().grid,
            TrajectoryParams::default().cost,
        )
        .unwrap(),
    )
}

/// A pool of the fixture's first `n` episodes in the scene of `ctx`.
fn one_scene_pool(f: &Fixture, ctx: &Arc<SceneContext>, n: usize) -> Arc<sage_env::Pool> {
    let entries = f
        .episodes
        .iter()
        .take(n)
        .map(|e| sage_env::PoolEpisode {
            scene: 0,
            scene_name: "home".into(),
            episode: e.clone(),
        })
        .collect();
    Arc::new(sage_env::Pool::new(vec![ctx.clone()], entries).unwrap())
}

#[test]
fn gpu_environments_share_one_upload_per_scene() {
    let f = fixture();
    // A context of its own: other tests' environments do not count.
    let ctx = own_context(f);
    let mut cfg = tiny_camera();
    cfg.device = Device::Gpu;
    assert_eq!(ctx.uploads(), 0);
    let envs: Vec<Env> = (0..3)
        .map(|_| Env::new(ctx.clone(), cfg.clone()).unwrap())
        .collect();
    assert_eq!(ctx.uploads(), 1);
    for env in &envs {
        let device = env.render_device().unwrap();
        assert!(device.starts_with("gpu: "), "{device}");
    }
    // Environments that render nothing open no renderer.
    let mut blind_gpu = blind();
    blind_gpu.device = Device::Gpu;
    assert_eq!(
        Env::new(ctx.clone(), blind_gpu).unwrap().render_device(),
        None
    );
    cfg.device = Device::Cpu;
    let cpu = Env::new(ctx.clone(), cfg.clone()).unwrap();
    assert!(cpu.render_device().unwrap().starts_with("cpu ("));
    assert_eq!(ctx.uploads(), 1);
    cfg.device = Device::Auto;
    let auto = Env::new(ctx.clone(), cfg).unwrap();
    let device = auto.render_device().unwrap();
    if device.starts_with("gpu: ") {
        assert!(!device.contains("software"), "auto took {device}");
        assert_eq!(ctx.uploads(), 2);
    } else {
        assert!(
            device.starts_with("cpu (") && device.contains("auto: "),
            "{device}"
        );
        assert_eq!(ctx.uploads(), 1);
    }
}

/// The GPU forms the CPU's images: same sizes, RGB within 40 dB PSNR, depth and labels where
/// both see the same thing; a vector environment on the GPU (one batch per scene) gives the
/// single environments' images.
#[test]
fn gpu_observations_match_the_cpu() {
    use sage_env::pool::Order;
    use sage_env::{PooledEnv, VecEnv};
    use sage_metrics::Mode;
    let f = fixture();
    let mut cfg = tiny_camera();
    cfg.sensors.width = 64;
    cfg.sensors.height = 48;
    cfg.sensors.instance = true;
    let mut gpu_cfg = cfg.clone();
    gpu_cfg.device = Device::Gpu;
    let mut cpu = Env::new(f.ctx.clone(), cfg).unwrap();
    let mut gpu = Env::new(f.ctx.clone(), gpu_cfg.clone()).unwrap();
    let e = &f.episodes[0];
    let mut pairs = vec![(cpu.reset(e).unwrap(), gpu.reset(e).unwrap())];
    for a in [Action::MoveForward, Action::TurnLeft, Action::LookDown] {
        pairs.push((cpu.step(a).unwrap().0, gpu.step(a).unwrap().0));
    }
    for (c, g) in &pairs {
        assert_eq!((c.pose, c.pitch, c.step), (g.pose, g.pitch, g.step));
        let (ci, gi) = (c.images.as_ref().unwrap(), g.images.as_ref().unwrap());
        assert_eq!(
            (ci.width, ci.height, ci.depth_size),
            (gi.width, gi.height, gi.depth_size)
        );
        let (cr, gr) = (ci.rgb.as_ref().unwrap(), gi.rgb.as_ref().unwrap());
        assert_eq!(cr.len(), gr.len());
        let mse = cr
            .iter()
            .zip(gr)
            .map(|(&a, &b)| (f64::from(a) - f64::from(b)).powi(2))
            .sum::<f64>()
            / cr.len() as f64;
        let psnr = 10.0 * (255.0f64.powi(2) / mse.max(1e-12)).log10();
        assert!(psnr >= 40.0, "RGB PSNR {psnr:.1} dB");
        let (cd, gd) = (ci.depth.as_ref().unwrap(), gi.depth.as_ref().unwrap());
        let near = cd
            .iter()
            .zip(gd)
            .filter(|(a, b)| (*a - *b).abs() <= 0.01 * a.max(**b) + 1e-3)
            .count();
        assert!(near * 100 >= cd.len() * 98, "{near} of {} depths", cd.len());
        let (cs, gs) = (ci.instance.as_ref().unwrap(), gi.instance.as_ref().unwrap());
        let same = cs.iter().zip(gs).filter(|(a, b)| a == b).count();
        assert!(
            same * 100 >= cs.len() * 98,
            "{same} of {} instances",
            cs.len()
        );
    }
    let pool = one_scene_pool(f, &f.ctx, 3);
    let mut vec_env = VecEnv::new(3, pool.clone(), gpu_cfg.clone(), Mode::Sage).unwrap();
    let batch = vec_env.run((0..3).map(Order::Reset).collect()).unwrap();
    for (i, t) in batch.iter().enumerate() {
        let mut single = PooledEnv::new(pool.clone(), gpu_cfg.clone(), Mode::Sage);
        assert_eq!(single.reset(i).unwrap().obs, t.obs, "sub-environment {i}");
    }
}

#[test]
fn the_gnbench_preset_renders_480_by_360_and_its_mode_scores_on_the_occupancy_image() {
    use sage_metrics::Mode;
    use sage_metrics::gnbench::GnBenchDistances;
    let f = fixture();
    let mut env = Env::new(f.ctx.clone(), EnvConfig::preset("gnbench").unwrap()).unwrap();
    let e = &f.episodes[0];
    let im = env.reset(e).unwrap().images.unwrap();
    assert_eq!((im.width, im.height), (480, 360));
    assert_eq!(im.rgb.as_ref().unwrap().len(), 480 * 360 * 3);
    assert!(im.depth.is_none());
    // The oracle's trace, scored as GN-Bench: the record carries a distance per position,
    // computed on the occupancy image; other modes leave them out.
    let mut blind_env = Env::new(f.ctx.clone(), blind()).unwrap();
    let trace = run_episode(&mut blind_env, &mut OracleAgent::new(0.25), e).unwrap();
    let record = sage_env::scoring::metric_record(&f.ctx, &trace, Mode::GnBench);
    let d: &GnBenchDistances = record.gnbench.as_ref().unwrap();
    assert_eq!(d.steps.len(), trace.steps.len());
    let start = d
        .start
        .expect("the goal is reachable on the occupancy image");
    assert!(start > 0.0);
    let m = sage_metrics::evaluate(&record, Mode::GnBench).unwrap();
    // The oracle ends within a metre of its goal, well inside GN-Bench's 3 m.
    assert_eq!(m.osr, Some(1.0));
    assert!(m.ne.unwrap() < 3.0, "{m:?}");
    assert_eq!((m.cr, m.ndtw), (None, None));
    assert!(
        sage_env::scoring::metric_record(&f.ctx, &trace, Mode::Sage)
            .gnbench
            .is_none()
    );
    // The same scene's grids are built once and shared.
    assert!(std::ptr::eq(
        f.ctx.gnbench_grid().unwrap(),
        f.ctx.gnbench_grid().unwrap()
    ));
}

/// CPU environments over a scene render with the scene's one pool of renderers: a vector
/// environment of many holds the frame buffers of the renders that ran at once, not one set
/// per environment, and forms the images a renderer of its own would.
#[test]
fn cpu_environments_share_the_scenes_renderers() {
    use sage_env::VecEnv;
    use sage_env::pool::Order;
    use sage_metrics::Mode;
    let f = fixture();
    // A context of its own: other tests' environments do not count.
    let ctx = own_context(f);
    let pool = one_scene_pool(f, &ctx, 4);
    let envs = 16;
    let threads = 2;
    let workers = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let (resets, steps) = workers.install(|| {
        let mut vec_env = VecEnv::new(envs, pool.clone(), tiny_camera(), Mode::Sage).unwrap();
        let resets = vec_env
            .run((0..envs).map(|i| Order::Reset(i % 4)).collect())
            .unwrap();
        let steps = vec_env
            .run((0..envs).map(|_| Order::Step(Action::TurnLeft)).collect())
            .unwrap();
        (resets, steps)
    });
    assert!(ctx.cpu_renderers() >= 1);
    assert!(
        ctx.cpu_renderers() < envs,
        "{} renderers for {envs} environments",
        ctx.cpu_renderers()
    );
    // The images are those of an environment over a context of its own.
    for i in [0, 5, 15] {
        let mut env = Env::new(own_context(f), tiny_camera()).unwrap();
        let obs = env.reset(&f.episodes[i % 4]).unwrap();
        assert_eq!(obs.images, resets[i].obs.images, "reset of environment {i}");
        let (obs, _) = env.step(Action::TurnLeft).unwrap();
        assert_eq!(obs.images, steps[i].obs.images, "step of environment {i}");
    }
}

#[test]
fn a_scene_without_gaussians_has_no_renderer_to_give() {
    let f = fixture();
    let mut scene = f.ctx.scene.clone();
    scene.gaussians = sage_scene::Gaussians::new(0).unwrap();
    let params = TrajectoryParams::default();
    let ctx = SceneContext::new(scene, f.bodies.clone(), &params.grid, params.cost).unwrap();
    // Paths and physics need no Gaussians; views of nothing would be black, so are refused.
    let Err(e) = ctx.renderer(Device::Cpu) else {
        panic!("a renderer of no Gaussians");
    };
    let e = e.to_string();
    assert!(
        e.contains("has no Gaussians to render") && e.contains("3dgs_compressed.ply"),
        "{e}"
    );
    assert!(f.ctx.renderer(Device::Cpu).is_ok());
}
