//! Writing datasets: files per spec/DATASET.md that the core readers load unchanged.

use stripecal::io::read_truth;
use stripecal::model::{Dataset, RobotReading, Scan};
use stripecal_sim::{SimConfig, Twin};

#[test]
fn written_datasets_load_with_the_core_readers() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = SimConfig::hp3_paper()
        .with_overrides(
            &serde_json::json!({"seed": 11, "scan": {"max_frames": 6}, "poses": {"count": 4}}),
        )
        .unwrap();
    let twin = Twin::new(cfg).unwrap();
    let mut calls = 0;
    let summary = twin.write(dir.path(), &mut |_, _, _| calls += 1).unwrap();
    assert!(calls >= 4 + 6);
    let ds = Dataset::load(dir.path().join("calib")).unwrap();
    assert_eq!(ds.views.len(), 4);
    assert_eq!(ds.rig.width, 768);
    assert_eq!(ds.rig.robot.as_ref().unwrap(), &twin.robot_nominal);
    for (v, info) in ds.views.iter().zip(&summary.views) {
        match &v.reading {
            RobotReading::Joints(q) => assert_eq!(q, &info.q_deg),
            other => panic!("unexpected reading {other:?}"),
        }
        let img = stripecal::io::load_gray(ds.image_path(&v.board_image)).unwrap();
        assert_eq!(img.size(), (768, 576));
    }
    let truth = read_truth(dir.path().join("calib/truth.json")).unwrap();
    assert_eq!(truth.camera, twin.camera);
    assert!((truth.hand_cam.translation.vector - twin.hand_cam.translation.vector).norm() < 1e-12);
    let images = truth.extra["images"].as_array().unwrap();
    assert_eq!(images.len(), 4);
    assert_eq!(images[0]["circles"].as_array().unwrap().len(), 88);
    let scan = Scan::load(dir.path().join("scan"), None).unwrap();
    assert_eq!(scan.frames.len(), 6);
    let st = read_truth(dir.path().join("scan/truth.json")).unwrap();
    let sphere = st.sphere.unwrap();
    assert!((sphere.diameter_mm - 44.8614).abs() < 1e-12);
    // no staging folders left behind
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().starts_with('.'))
        .collect();
    assert!(leftovers.is_empty());
}

#[test]
fn single_image_mode_writes_one_image_per_view() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = SimConfig::hp3_paper()
        .with_overrides(
            &serde_json::json!({"seed": 2, "scan": {"enabled": false}, "poses": {"count": 3},
            "imaging": {"single_image": true, "bit_depth": 16}}),
        )
        .unwrap();
    let twin = Twin::new(cfg).unwrap();
    twin.write(dir.path(), &mut |_, _, _| {}).unwrap();
    let ds = Dataset::load(dir.path().join("calib")).unwrap();
    for v in &ds.views {
        assert_eq!(v.laser_image.as_ref(), Some(&v.board_image));
        let img = stripecal::io::load_gray(ds.image_path(&v.board_image)).unwrap();
        assert!(matches!(img, stripecal::model::image::AnyGray::U16(_)));
    }
    assert!(!dir.path().join("scan").exists());
}

#[test]
fn impossible_pose_constraints_are_a_clear_error() {
    let cfg = SimConfig::hp3_paper()
        .with_overrides(&serde_json::json!({"poses": {"standoff_mm": [20.0, 25.0]}}))
        .unwrap();
    let twin = Twin::new(cfg).unwrap();
    let err = twin.calibration_poses().unwrap_err().to_string();
    assert!(err.contains("valid poses"), "{err}");
}

#[test]
fn dh_errors_change_the_true_robot_only() {
    let cfg = SimConfig::hp3_paper()
        .with_overrides(&serde_json::json!({"dh_errors": [[0.05, 0, 0.2, 0], [0, 0.01, 0, 0], [0, 0, 0, 0], [0, 0, 0, 0.1], [0, 0, 0, 0], [0.02, 0, 0, 0]]}))
        .unwrap();
    let twin = Twin::new(cfg).unwrap();
    assert!(
        (twin.robot_true.joints[0].a_mm - twin.robot_nominal.joints[0].a_mm - 0.2).abs() < 1e-12
    );
    assert_eq!(twin.robot_nominal, stripecal::Robot::hp3());
    let truth = twin.truth(false);
    assert_eq!(truth.robot.unwrap(), twin.robot_true);
}

/// `poses.reading_noise_deg`: the reported readings (views.csv, the observations' robot
/// poses) carry Gaussian noise of that sigma, reproducibly by seed; the true poses (the
/// images) do not move; zero noise reports the true readings.
#[test]
fn reading_noise_moves_the_reported_readings_only() {
    let cfg = |noise: f64| {
        SimConfig::hp3_paper()
            .with_overrides(&serde_json::json!({"poses": {"count": 8, "reading_noise_deg": noise}}))
            .unwrap()
    };
    let exact = Twin::new(cfg(0.0)).unwrap();
    let noisy = Twin::new(cfg(0.02)).unwrap();
    let poses = exact.calibration_poses().unwrap();
    assert_eq!(poses, noisy.calibration_poses().unwrap());
    let (a, b) = (
        exact.exact_observations().unwrap(),
        noisy.exact_observations().unwrap(),
    );
    let mut d = Vec::new();
    for (i, ((va, vb), p)) in a.iter().zip(&b).zip(&poses).enumerate() {
        assert_eq!(va.circles, vb.circles, "the images are the true poses'");
        assert_eq!(exact.reported_q(i, &p.q_deg), p.q_deg);
        let q = noisy.reported_q(i, &p.q_deg);
        assert_eq!(q, noisy.reported_q(i, &p.q_deg));
        assert_eq!(vb.reading, Some(RobotReading::Joints(q.clone())));
        assert_eq!(vb.base_hand, Some(noisy.robot_true.forward(&q).unwrap()));
        d.extend(q.iter().zip(&p.q_deg).map(|(x, y)| x - y));
    }
    let rms = (d.iter().map(|x| x * x).sum::<f64>() / d.len() as f64).sqrt();
    // 48 draws: the RMS within 30 % of the sigma.
    assert!((0.014..0.026).contains(&rms), "{rms}");
    let e = SimConfig::hp3_paper()
        .with_overrides(&serde_json::json!({"poses": {"reading_noise_deg": -1.0}}))
        .unwrap_err();
    assert!(e.to_string().contains("poses.reading_noise_deg"), "{e}");
}

/// `hp3-sheet`: every pose puts the stripe mostly on the sheet beside the pattern and
/// across the sheet's edge onto the table, `board.plate_thickness_mm` deep behind it
/// (the default elsewhere: [`stripecal_sim::dataset::PLATE_THICKNESS_MM`]).
#[test]
fn sheet_preset_puts_the_stripe_beside_the_pattern_across_a_depth_step() {
    use stripecal_sim::poses::stripe_layout;
    assert_eq!(
        SimConfig::hp3_paper().board.plate_thickness_mm,
        stripecal_sim::dataset::PLATE_THICKNESS_MM
    );
    let twin = Twin::new(SimConfig::preset("hp3-sheet").unwrap()).unwrap();
    assert!(twin.cfg.imaging.single_image && twin.cfg.poses.stripe_beside_pattern);
    let poses = twin.calibration_poses().unwrap();
    assert_eq!(poses.len(), 15);
    for p in &poses {
        let scene = twin.scene(&p.q_deg, false).unwrap();
        let (_, plate_d) = scene.plate_plane();
        let (_, table_d) = scene.table_plane();
        assert!((table_d - plate_d - 4.0).abs() < 1e-12);
        let l = stripe_layout(&scene, &twin.camera);
        assert!(
            l.sheet_mm >= 2.0 * l.pattern_mm && l.sheet_mm >= l.table_mm,
            "{l:?}"
        );
        assert!(l.table_mm >= 2.0 * twin.board.pitch_mm, "{l:?}");
    }
    let e = SimConfig::hp3_paper()
        .with_overrides(&serde_json::json!({"board": {"plate_thickness_mm": -1.0}}))
        .unwrap_err();
    assert!(e.to_string().contains("plate_thickness_mm"), "{e}");
}
