//! Inverse kinematics on random reachable poses (the tip pose of a random
//! configuration inside the joint limits), per arm: success rate and time
//! per solve (median, p95), numerical IK for any chain from its URDF and,
//! for the UR5, the closed form beside it.
//!
//!     cargo bench --bench ik                  (10,000 poses per arm)
//!     IK_POSES=1000 cargo bench --bench ik
//!
//! The UR5 is the built-in one (its closed form beside it); the others are
//! the shipped descriptions in `robots/` (UR5 and UR10 as ROS-Industrial
//! describes them, Franka Panda, KUKA iiwa). Asserts nothing; run with
//! nothing else busy on the machine.

use std::time::Instant;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use treemanip::eval::plan::percentile;
use treemanip::robot::kinematics::numeric_ik::{IkOptions, solve};
use treemanip::robot::model::description::RobotDescription;
use treemanip::robot::model::urdf_chain::Chain;
use treemanip::robot::model::urdf_chain::random_configuration;
use treemanip::robot::{Arm, ur5};

/// The shipped robot descriptions (`robots/*.toml`): name, chain, home.
fn shipped() -> Vec<(String, Chain, Vec<f64>)> {
    ["ur5", "ur10", "panda", "iiwa"]
        .iter()
        .map(|name| {
            let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("robots")
                .join(format!("{name}.toml"));
            let text = std::fs::read_to_string(&path).unwrap();
            let d = RobotDescription::from_toml_str(&text, &path).unwrap();
            let chain = d.chain().unwrap();
            (format!("{name} ({} joints)", d.dof), chain, d.home.clone())
        })
        .collect()
}

fn report(name: &str, times_us: &mut [f64], solved: usize, poses: usize) {
    times_us.sort_by(f64::total_cmp);
    println!(
        "{name:<28} {:>8.2}% {:>10.1} {:>10.1} {:>10.1}",
        100.0 * solved as f64 / poses as f64,
        percentile(times_us, 0.5),
        percentile(times_us, 0.95),
        times_us.iter().sum::<f64>() / times_us.len().max(1) as f64
    );
}

fn main() {
    let poses: usize = std::env::var("IK_POSES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(10_000);
    let cpu = treemanip::nn::train::checkpoint::cpu_model();
    println!("IK on {poses} random reachable poses per arm, CPU {cpu}, one thread");
    println!(
        "{:<28} {:>9} {:>10} {:>10} {:>10}",
        "arm / solver", "success", "p50 µs", "p95 µs", "mean µs"
    );
    let ur5_chain = Chain::from_urdf_str(ur5::URDF, Some("base_link"), Some("tool")).unwrap();
    let mut arms = vec![("UR5".to_owned(), ur5_chain.clone(), ur5::HOME.to_vec())];
    arms.extend(shipped());
    for (name, chain, reference) in &arms {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let goals: Vec<_> = (0..poses)
            .map(|_| chain.tip_pose(&random_configuration(chain, &mut rng)))
            .collect();
        let mut times = Vec::with_capacity(poses);
        let mut solved = 0;
        for (k, goal) in goals.iter().enumerate() {
            let options = IkOptions {
                seed: k as u64,
                ..IkOptions::default()
            };
            let started = Instant::now();
            let q = solve(chain, goal, reference, &options);
            times.push(started.elapsed().as_secs_f64() * 1e6);
            solved += usize::from(q.is_some());
        }
        report(&format!("{name}, numerical"), &mut times, solved, poses);
        if let Some(ur) = treemanip::robot::kinematics::ur_kinematics::UrKinematics::detect(chain) {
            // The closed form derived from the URDF, on the same poses.
            let reference: [f64; 6] = std::array::from_fn(|i| reference[i]);
            let mut times = Vec::with_capacity(poses);
            let mut solved = 0;
            for goal in &goals {
                let started = Instant::now();
                let solutions = ur.solve(goal, &reference);
                times.push(started.elapsed().as_secs_f64() * 1e6);
                solved += usize::from(!solutions.is_empty());
            }
            report(
                &format!("{name}, closed form (fitted DH)"),
                &mut times,
                solved,
                poses,
            );
        }
        if name == "UR5" {
            // The closed form on the same poses (tool frame, base at the
            // origin), the fast path for UR kinematics.
            let arm = Arm::default().with_base(nalgebra::Isometry3::identity());
            let mut times = Vec::with_capacity(poses);
            let mut solved = 0;
            for goal in &goals {
                let started = Instant::now();
                let solutions = arm.inverse_kinematics(goal, &ur5::HOME);
                times.push(started.elapsed().as_secs_f64() * 1e6);
                solved += usize::from(!solutions.is_empty());
            }
            report("UR5, closed form", &mut times, solved, poses);
        }
    }
}
