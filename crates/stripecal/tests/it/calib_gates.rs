//! Issue 13: never a confident wrong calibration. Views whose robot poses do not fit
//! their images (swapped pairs, a pose column shifted by a row) on the twin's noisy
//! observations: named, left out when enough agree, a failed calibration otherwise.
//!
//! `cargo test -p stripecal --test it calib_gates:: -- --nocapture` prints the figures.

use stripecal::calib::ViewObs;
use stripecal::model::{Calibration, Rig};
use stripecal::pipeline::{calibrate_observations, CalibrateOptions, CalibrationReport};
use stripecal::Error;
use stripecal_sim::rng::Rng;
use stripecal_sim::{noisy_observations, SimConfig, Twin};

/// 15 views of the paper's rig with 0.05 px circle noise and 0.1 px stripe noise (about
/// what the detector measures at noise 4), and the rig.
fn views15() -> (Vec<ViewObs>, Rig) {
    let cfg = SimConfig::hp3_paper()
        .with_overrides(&serde_json::json!({"poses": {"count": 15}}))
        .unwrap();
    let t = Twin::new(cfg).unwrap();
    let exact = t.exact_observations().unwrap();
    let mut rng = Rng::new(13, 0);
    (
        noisy_observations(&exact, 0.05, 0.1, &mut rng),
        t.rig().unwrap(),
    )
}

/// The images of views `i` and `j` swapped (their robot poses stay on their rows).
fn swap_images(views: &[ViewObs], i: usize, j: usize) -> Vec<ViewObs> {
    let mut v = views.to_vec();
    let (bi, bj) = (v[i].base_hand, v[j].base_hand);
    let (ri, rj) = (v[i].reading.clone(), v[j].reading.clone());
    v[i].base_hand = bj;
    v[j].base_hand = bi;
    v[i].reading = rj;
    v[j].reading = ri;
    v
}

fn failure(r: stripecal::Result<CalibrationReport>) -> Box<stripecal::model::QualityFailure> {
    match r {
        Err(Error::Quality(f)) => f,
        Err(e) => panic!("expected a quality failure, got {e}"),
        Ok(rep) => panic!(
            "expected a quality failure, got a calibration: {:?}",
            rep.calibration.quality.checks
        ),
    }
}

/// `(value, sigma)` of every estimated number under the covariance's names.
fn values(c: &Calibration) -> Vec<(String, f64, f64)> {
    let cov = c.covariance.as_ref().expect("a covariance");
    let cam = &c.camera;
    let plane = c.laser_plane.expect("a plane");
    let x = stripecal::model::geometry::iso_to_rotvec(&c.hand_cam);
    let z = stripecal::model::geometry::iso_to_rotvec(&c.base_board);
    let mut out = vec![
        ("camera.fu", cam.fu),
        ("camera.fv", cam.fv),
        ("camera.u0", cam.u0),
        ("camera.v0", cam.v0),
        ("laser_plane.d_mm", plane.d),
    ];
    for k in 0..3 {
        out.push((
            [
                "laser_plane.normal[0]",
                "laser_plane.normal[1]",
                "laser_plane.normal[2]",
            ][k],
            plane.normal[k],
        ));
    }
    let names = |p: &'static str| {
        [
            format!("{p}.rotation_vector[0]"),
            format!("{p}.rotation_vector[1]"),
            format!("{p}.rotation_vector[2]"),
            format!("{p}.translation_mm[0]"),
            format!("{p}.translation_mm[1]"),
            format!("{p}.translation_mm[2]"),
        ]
    };
    let mut v: Vec<(String, f64, f64)> = out
        .into_iter()
        .map(|(n, x)| (n.to_string(), x, cov.sigma(n).unwrap()))
        .collect();
    for (p, (w, t)) in [("hand_cam", x), ("base_board", z)] {
        for (k, n) in names(p).into_iter().enumerate() {
            let val = if k < 3 { w[k] } else { t[k - 3] };
            let s = cov.sigma(&n).unwrap();
            v.push((n, val, s));
        }
    }
    v
}

#[test]
fn two_swapped_of_fifteen_are_left_out_and_the_rest_matches_the_clean_calibration() {
    let (views, rig) = views15();
    let opts = CalibrateOptions {
        leave_one_out: false,
        ..Default::default()
    };
    let clean = calibrate_observations(&views, &rig, &opts).unwrap();
    assert!(clean
        .calibration
        .quality
        .checks
        .iter()
        .all(|c| c.passed && c.views.is_empty()));
    // 2 of 15 swapped
    let bad = swap_images(&views, 2, 9);
    let rep = calibrate_observations(&bad, &rig, &opts).unwrap();
    let pairing = &rep.calibration.quality.checks[0];
    println!("{}", pairing.message);
    assert_eq!(pairing.name, "pairing");
    assert!(pairing.passed);
    assert_eq!(pairing.views, [2, 9]);
    assert!(pairing.message.contains("views 2 and 9 look swapped"));
    assert_eq!(rep.calibration.quality.views_used, 13);
    // the clean 13-view calibration
    let thirteen: Vec<ViewObs> = views
        .iter()
        .filter(|v| v.view != 2 && v.view != 9)
        .cloned()
        .collect();
    let reference = calibrate_observations(&thirteen, &rig, &opts).unwrap();
    let (a, b) = (values(&rep.calibration), values(&reference.calibration));
    let worst = a
        .iter()
        .zip(&b)
        .map(|((_, x, _), (_, y, s))| (x - y).abs() / s)
        .fold(0.0, f64::max);
    println!("largest |difference| / sigma against the clean 13 views: {worst:.3e}");
    for ((n, x, _), (_, y, s)) in a.iter().zip(&b) {
        assert!((x - y).abs() <= *s, "{n}: {x} vs clean 13 views {y} +- {s}");
    }
}

#[test]
fn two_swapped_of_five_fail_naming_both_views() {
    let (views, rig) = views15();
    let five = swap_images(&views[..5], 1, 3);
    let f = failure(calibrate_observations(
        &five,
        &rig,
        &CalibrateOptions::default(),
    ));
    println!("{f}");
    assert_eq!(f.failed.len(), 1);
    assert_eq!(f.failed[0].name, "pairing");
    assert_eq!(f.failed[0].views, [1, 3]);
    let msg = f.to_string();
    assert!(msg.contains("views 1 and 3"), "{msg}");
    assert!(msg.contains("3 of 5 views agree"), "{msg}");
    // the calibration of the 3 views that agree, for inspection
    let rep = f.report().cloned().expect("a calibration to inspect");
    assert_eq!(rep.calibration.quality.views_used, 3);
    // --accept-poor returns it, marked
    let opts = CalibrateOptions {
        accept_poor: true,
        ..Default::default()
    };
    let rep = calibrate_observations(&five, &rig, &opts).unwrap();
    assert!(rep.calibration.quality.accepted_poor);
    assert!(!rep.calibration.quality.checks[0].passed);
    // the clean five pass
    let ok = calibrate_observations(&views[..5], &rig, &CalibrateOptions::default()).unwrap();
    assert!(!ok.calibration.quality.accepted_poor);
}

#[test]
fn a_pose_column_one_row_off_is_reported_as_such() {
    let (views, rig) = views15();
    for shift in [1isize, -1] {
        // row k holds the robot pose of image k - shift
        let mut v = views.clone();
        for (k, vk) in v.iter_mut().enumerate() {
            let src = k as isize - shift;
            let (bh, rd) = if (0..15).contains(&src) {
                (
                    views[src as usize].base_hand,
                    views[src as usize].reading.clone(),
                )
            } else {
                (None, None) // the row the shift emptied
            };
            vk.base_hand = bh;
            vk.reading = rd;
        }
        let v: Vec<ViewObs> = v.into_iter().filter(|x| x.base_hand.is_some()).collect();
        let f = failure(calibrate_observations(
            &v,
            &rig,
            &CalibrateOptions::default(),
        ));
        let msg = f.to_string();
        println!("{msg}");
        assert!(!f.has_inspection());
        assert!(msg.contains("off by one row against the images"), "{msg}");
        let word = if shift == 1 {
            "further down"
        } else {
            "further up"
        };
        assert!(msg.contains(word), "{msg}");
    }
}

#[test]
fn undetermined_numbers_fail_the_determined_gate() {
    use stripecal::pipeline::gates::{determined, UNDETERMINED_FRACTION};
    let (views, rig) = views15();
    let rep = calibrate_observations(&views[..6], &rig, &CalibrateOptions::default()).unwrap();
    let adj = rep.adjustment.clone();
    let cam = &rep.calibration.camera;
    assert!(determined(&adj, cam, Some(300.0)).passed);
    // X's translation along z known to 20 mm at a 300 mm stand-off: beyond 5 %
    let mut a = adj.clone();
    a.sigma.hand_cam.translation_mm[2] = 20.0;
    let c = determined(&a, cam, Some(300.0));
    assert!(
        !c.passed && c.message.contains("hand_cam.translation_mm[2]"),
        "{}",
        c.message
    );
    // just inside the limit passes
    a.sigma.hand_cam.translation_mm[2] = 0.99 * UNDETERMINED_FRACTION * 300.0;
    assert!(determined(&a, cam, Some(300.0)).passed);
    // a focal length without a sigma (rank deficiency)
    let mut b = adj.clone();
    b.sigma.camera[0] = f64::NAN;
    let c = determined(&b, cam, Some(300.0));
    assert!(!c.passed && c.message.contains("fu"), "{}", c.message);
    let mut u = adj;
    u.unobservable = vec!["k3".into()];
    assert!(!determined(&u, cam, None).passed);
}
