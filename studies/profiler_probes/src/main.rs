//! Probes of the profiler's calibration on synthetic sphere profiles (15 views of an
//! 80 mm sphere, noise 0.01 mm, 1 % spikes; [`scene`]): `timing` (one calibration
//! without leave-one-out), `parts` (the arcs, the arcs with the consensus, the
//! adjustment) and `coverage` (the hand-eye's and the centre's errors in units of
//! their sigmas over 20 seeds). Formerly ignored tests of
//! crates/stripecal/src/pipeline/profile/tests.rs (`timing_probe`, `timing_parts`,
//! `coverage_probe`).

mod scene;

use std::time::Instant;

use stripecal::calib::joint::profile::{profile_adjustment, ProfileOptions};
use stripecal::calib::profile::arc::{find_arc, ArcOptions};
use stripecal::model::geometry::iso_to_rotvec;
use stripecal::model::ProfileRig;
use stripecal::pipeline::profile::{calibrate_profiles, prepare, ProfileCalibrateOptions};

/// Repetitions a timing is averaged over.
const REPS: usize = 20;

fn rig(diameter: Option<f64>) -> ProfileRig {
    ProfileRig {
        robot: None,
        invalid_z: None,
        diameter_mm: diameter,
    }
}

/// Milliseconds per call of `f` over [`REPS`] calls, and its last result.
fn timed<T>(mut f: impl FnMut() -> T) -> (f64, T) {
    let t = Instant::now();
    let mut last = f();
    for _ in 1..REPS {
        last = f();
    }
    (t.elapsed().as_secs_f64() * 1e3 / REPS as f64, last)
}

/// One calibration (no leave-one-out), declared diameter.
fn timing() {
    let s = scene::scene(15, 1, 0.01, None);
    let n: usize = s.inputs.iter().map(|i| i.profile.points.len()).sum();
    let opts = ProfileCalibrateOptions {
        leave_one_out: false,
        ..Default::default()
    };
    let (ms, _) = timed(|| calibrate_profiles(&s.inputs, &rig(Some(s.diameter)), &opts).unwrap());
    println!("{n} points: {ms:.2} ms per calibration");
}

/// The parts: each profile's arc, the arcs with the consensus and its start
/// (`pipeline::profile::prepare`), the adjustment from that start.
fn parts() {
    let s = scene::scene(15, 1, 0.01, None);
    let r = rig(Some(s.diameter));
    // pipeline::profile's arc options for a declared diameter (its `arc_options`).
    let aopts = ArcOptions {
        max_radius: 0.5 * s.diameter * 1.02 + 0.2,
        ..ArcOptions::default()
    };
    let (ms, _) = timed(|| {
        s.inputs
            .iter()
            .map(|i| find_arc(&i.profile.points, &aopts, 1).unwrap())
            .collect::<Vec<_>>()
    });
    println!("arcs {ms:.2} ms");
    let (ms, prep) = timed(|| prepare(&s.inputs, &r).unwrap());
    println!("arcs and consensus {ms:.2} ms");
    let (ms, fit) =
        timed(|| profile_adjustment(&prep.views, &prep.start, &ProfileOptions::default()).unwrap());
    println!("adjustment {ms:.2} ms ({} iterations)", fit.iterations);
}

/// The hand-eye's translation and the sphere centre against the truth in units of their
/// sigmas, seeds 101..=120.
fn coverage() {
    let mut z = Vec::new();
    for seed in 1..=20 {
        let s = scene::scene(15, 100 + seed, 0.01, None);
        let rep =
            calibrate_profiles(&s.inputs, &rig(Some(s.diameter)), &Default::default()).unwrap();
        let c = &rep.calibration;
        let (_, t) = iso_to_rotvec(&c.hand_sensor);
        let cov = c.covariance.as_ref().unwrap();
        for k in 0..3 {
            let sd = cov.sigma(&format!("hand_cam.translation_mm[{k}]")).unwrap();
            z.push((t[k] - s.x.translation.vector[k]) / sd);
            let sd = cov.sigma(&format!("sphere.center_mm[{k}]")).unwrap();
            z.push((c.sphere_center_mm[k] - s.centre[k]) / sd);
        }
        println!("seed {seed}: k {:.2}", rep.fit.view_variance_factor);
    }
    let inside = z.iter().filter(|x| x.abs() < 3.0).count();
    let rms = (z.iter().map(|x| x * x).sum::<f64>() / z.len() as f64).sqrt();
    println!("{inside}/{} inside 3 sigma, rms z {rms:.2}", z.len());
}

fn main() {
    let what: Vec<String> = std::env::args().skip(1).collect();
    let all = what.is_empty();
    for (name, probe) in [
        ("timing", timing as fn()),
        ("parts", parts),
        ("coverage", coverage),
    ] {
        if all || what.iter().any(|w| w == name) {
            probe();
        }
    }
}
