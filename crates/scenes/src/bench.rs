//! Physics throughput of a scene: the raw `mj_step` loop, the [`World`] step path, and many
//! worlds on many threads. Figures are ratios against the raw loop of the same model.

use crate::world::{World, WorldModel};
use mujoco_rs::prelude::*;
use rayon::prelude::*;
use std::sync::Arc;
use std::time::Instant;

/// Results of [`bench_world`], in physics steps per second.
#[derive(Debug, Clone)]
pub struct WorldBench {
    /// Physics steps per control tick in this scene.
    pub substeps: usize,
    /// A bare `mj_step` loop on one `mjData` of the scene's model.
    pub raw: f64,
    /// [`World::step`] on one world (PD targets written, substeps stepped).
    pub world: f64,
    /// (threads, total steps/s) for one world per thread.
    pub threads: Vec<(usize, f64)>,
}

/// Measures the scene's physics throughput with `steps` physics steps per measurement, each
/// measurement repeated `repeats` times keeping the fastest (the least disturbed by other work on
/// the machine); the character holds the standing pose (reset every 10 simulated seconds, the
/// same way in every loop).
pub fn bench_world(model: &Arc<WorldModel>, steps: usize, repeats: usize, thread_counts: &[usize]) -> WorldBench {
    let best = |mut once: Box<dyn FnMut() -> f64 + '_>| (0..repeats.max(1)).map(|_| once()).fold(0.0, f64::max);
    let substeps = model.substeps();
    let ticks = steps.div_ceil(substeps);
    let reset_every = (10.0 / model.control_dt()) as usize;
    let standing: Vec<f64> = {
        let w = model.new_world();
        let mut a = vec![0.0; model.index.dof()];
        w.joint_angles(&mut a);
        a
    };

    // The raw loop: the same model, the same control values, no wrapper.
    let raw = {
        let mj = model.mj_model();
        let mut data = MjData::new(Arc::clone(mj));
        let start_qpos = mj.qpos0().to_vec();
        let prime = |data: &mut MjData<Arc<MjModel>>| {
            data.reset();
            data.qpos_mut().copy_from_slice(&start_qpos);
            for (j, &a) in model.index.joints.iter().zip(&standing) {
                data.ctrl_mut()[j.actuator] = a;
            }
        };
        prime(&mut data);
        let mut run = |n: usize| {
            for t in 0..n {
                if t % reset_every == 0 {
                    prime(&mut data);
                }
                for _ in 0..substeps {
                    data.step();
                }
            }
        };
        run(ticks / 10);
        best(Box::new(|| {
            let t0 = Instant::now();
            run(ticks);
            (ticks * substeps) as f64 / t0.elapsed().as_secs_f64()
        }))
    };

    let run_world = |w: &mut World, n: usize| {
        for t in 0..n {
            if t % reset_every == 0 {
                w.place_standing(0.0, 0.0, 0.0);
            }
            w.step(&standing).expect("standing action has the body's size");
        }
    };
    let world = {
        let mut w = model.new_world();
        run_world(&mut w, ticks / 10);
        best(Box::new(|| {
            let t0 = Instant::now();
            run_world(&mut w, ticks);
            (ticks * substeps) as f64 / t0.elapsed().as_secs_f64()
        }))
    };

    let threads = thread_counts
        .iter()
        .map(|&k| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(k).build().expect("thread pool");
            let mut worlds: Vec<World> = (0..k).map(|_| model.new_world()).collect();
            pool.install(|| worlds.par_iter_mut().for_each(|w| run_world(w, ticks / 10)));
            let rate = best(Box::new(|| {
                let t0 = Instant::now();
                pool.install(|| worlds.par_iter_mut().for_each(|w| run_world(w, ticks)));
                (k * ticks * substeps) as f64 / t0.elapsed().as_secs_f64()
            }));
            (k, rate)
        })
        .collect();

    WorldBench { substeps, raw, world, threads }
}
