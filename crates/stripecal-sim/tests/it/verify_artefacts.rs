//! Verification artefacts (issue 15): the twin's `verify/` folder, rendered once for the
//! module (one ball bar position and one plate position, a coarse sweep), read back with
//! the core readers and measured with the TRUE calibration against the truth.

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use nalgebra::Vector3;
use stripecal::io::read_truth;
use stripecal::reconstruct::{
    fit_plane, fit_sphere, load_scan, reconstruct_scan, FitOptions, ReconstructOptions, ScanPoints,
};
use stripecal_sim::{SimConfig, Twin};

struct Rendered {
    _dir: tempfile::TempDir,
    root: PathBuf,
    twin: Twin,
    frames: usize,
}

fn config(extra: serde_json::Value) -> SimConfig {
    let mut over = serde_json::json!({
        "seed": 4,
        "poses": {"count": 3},
        "scan": {"enabled": false},
        "verify": {"enabled": true, "bar_positions": 1, "plate_positions": 1, "step_mm": 2.0},
    });
    if let (Some(o), Some(e)) = (over.as_object_mut(), extra.as_object()) {
        for (k, v) in e {
            o.insert(k.clone(), v.clone());
        }
    }
    SimConfig::hp3_paper().with_overrides(&over).unwrap()
}

fn rendered() -> &'static Rendered {
    static R: OnceLock<Rendered> = OnceLock::new();
    R.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let twin = Twin::new(config(serde_json::json!({}))).unwrap();
        let s = twin.write(dir.path(), &mut |_, _, _| {}).unwrap();
        let root = s.verify_dir.clone().unwrap();
        assert_eq!(root, dir.path().join("verify"));
        Rendered {
            root,
            twin,
            frames: s.verify_frames,
            _dir: dir,
        }
    })
}

fn points(r: &Rendered, name: &str) -> ScanPoints {
    let cal = r.twin.true_calibration();
    let scan = load_scan(r.root.join(name), &cal).unwrap();
    reconstruct_scan(
        &cal,
        &scan,
        &ReconstructOptions::default(),
        &mut |_, _, _| ControlFlow::Continue(()),
    )
    .unwrap()
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

#[test]
fn verify_folder_has_the_manifest_and_the_contract_keys() {
    let r = rendered();
    assert_eq!(
        std::fs::read_to_string(r.root.join("verify.csv")).unwrap(),
        "scan,artefact\nbar_1,bar\nplate_1,plate\n"
    );
    let a = json(&r.root.join("artefacts.json"));
    assert_eq!(a["format"], "stripecal/artefacts@1");
    let spheres = a["spheres"].as_array().unwrap();
    assert_eq!(spheres.len(), 2);
    for (s, n) in spheres.iter().zip(["A", "B"]) {
        assert_eq!(s["name"], n);
        assert!(s["diameter_mm"].as_f64().unwrap() > 25.0);
        assert!(s["form_mm"].as_f64().unwrap() >= 0.0);
    }
    assert_eq!(a["ball_bars"][0]["name"], "bar");
    assert_eq!(a["ball_bars"][0]["spheres"], serde_json::json!(["A", "B"]));
    assert!(a["ball_bars"][0]["length_mm"].as_f64().is_some());
    assert_eq!(a["planes"][0]["name"], "plate");
    assert!(a["planes"][0]["flatness_mm"].as_f64().is_some());
    for k in ["diameter", "length", "flatness"] {
        assert!(a["uncertainty_k2_mm"][k].as_f64().is_some(), "{k}");
    }
    for k in ["probing_form", "probing_size", "sphere_spacing", "flatness"] {
        let v = a["mpe_mm"][k].as_f64().unwrap();
        assert!(v > 0.0 && v <= 0.1, "{k} {v}");
    }
    // certificate vs truth: within the stated uncertainty, never the same digits
    let bar = read_truth(r.root.join("bar_1/truth.json")).unwrap();
    let ts = bar.extra["spheres"].as_array().unwrap();
    let u = &a["uncertainty_k2_mm"];
    for (s, t) in spheres.iter().zip(ts) {
        let e = s["diameter_mm"].as_f64().unwrap() - t["diameter_mm"].as_f64().unwrap();
        assert!(e.abs() <= u["diameter"].as_f64().unwrap() + 1e-7, "{e}");
    }
    let l = bar.extra["length_mm"].as_f64().unwrap();
    let e = a["ball_bars"][0]["length_mm"].as_f64().unwrap() - l;
    assert!(e.abs() <= u["length"].as_f64().unwrap() + 1e-7, "{e}");
    assert!(r.frames > 10, "{} frames", r.frames);
    // truth.json: the true calibration, sphere = A, the plate's plane
    assert_eq!(bar.camera, r.twin.camera);
    assert_eq!(
        bar.sphere.unwrap().center_mm.x,
        ts[0]["center_mm"][0].as_f64().unwrap()
    );
    let plate = json(&r.root.join("plate_1/truth.json"));
    assert!(plate["plane"]["normal"].as_array().unwrap().len() == 3);
    // exact certificate on request
    let tw = Twin::new(config(serde_json::json!({
        "verify": {"enabled": true, "certificate_exact": true}
    })))
    .unwrap();
    let art = tw.verify_artefacts();
    assert_eq!(
        art.certificate["ball_bars"][0]["length_mm"]
            .as_f64()
            .unwrap(),
        (art.length_mm * 1e7).round() / 1e7
    );
    assert_eq!(art.certificate["planes"][0]["flatness_mm"], 0.0);
}

#[test]
fn ball_bar_scan_measures_the_true_spheres_and_length() {
    let r = rendered();
    let truth = read_truth(r.root.join("bar_1/truth.json")).unwrap();
    let sp = points(r, "bar_1");
    let mut centres = Vec::new();
    for t in truth.extra["spheres"].as_array().unwrap() {
        let c = Vector3::from_iterator(
            t["center_mm"]
                .as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap()),
        );
        let d = t["diameter_mm"].as_f64().unwrap();
        let near: Vec<[f64; 3]> = sp
            .points_mm
            .iter()
            .filter(|p| (Vector3::from(**p) - c).norm() < 0.5 * d + 2.0)
            .copied()
            .collect();
        let f = fit_sphere(
            &near,
            &FitOptions {
                diameter_range_mm: Some([d - 2.0, d + 2.0]),
                ..Default::default()
            },
        )
        .unwrap();
        let dc = f.center_mm - c;
        let dd = f.diameter_mm - d;
        eprintln!(
            "sphere {}: {} points ({} inliers), centre error [{:+.4}, {:+.4}, {:+.4}] ({:.4}) mm, \
             diameter error {:+.4} mm, rms {:.4} mm",
            t["name"],
            near.len(),
            f.points,
            dc.x,
            dc.y,
            dc.z,
            dc.norm(),
            dd,
            f.rms_mm
        );
        assert!(f.points > 1000, "{} inliers", f.points);
        assert!(dc.norm() < 0.01, "centre error {dc:?}");
        assert!(dd.abs() < 0.01, "diameter error {dd}");
        centres.push(f.center_mm);
    }
    let l = (centres[1] - centres[0]).norm();
    let lt = truth.extra["length_mm"].as_f64().unwrap();
    eprintln!("bar length error {:+.4} mm", l - lt);
    assert!((l - lt).abs() < 0.01, "length error {}", l - lt);
}

#[test]
fn plate_scan_measures_the_true_plane() {
    let r = rendered();
    let truth = json(&r.root.join("plate_1/truth.json"));
    let n = Vector3::from_iterator(
        truth["plane"]["normal"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap()),
    );
    let d = truth["plane"]["d_mm"].as_f64().unwrap();
    let sp = points(r, "plate_1");
    let f = fit_plane(&sp.points_mm, &FitOptions::default()).unwrap();
    let (fn_, fd) = if f.plane.normal.dot(&n) < 0.0 {
        (-f.plane.normal, -f.plane.d)
    } else {
        (f.plane.normal, f.plane.d)
    };
    let angle = fn_.angle(&n).to_degrees();
    let offset = fn_.dot(&f.centroid_mm) - fd;
    let dist = n.dot(&f.centroid_mm) - d;
    let worst = sp
        .points_mm
        .iter()
        .map(|p| (n.dot(&Vector3::from(*p)) - d).abs())
        .fold(0.0, f64::max);
    eprintln!(
        "plate: {} points ({} inliers), normal error {angle:.5} deg, centroid off the true \
         plane {dist:+.4} mm, rms {:.4} mm, flatness {:.4} mm, largest |distance| {worst:.4} mm",
        sp.points_mm.len(),
        f.points,
        f.rms_mm,
        f.flatness_mm
    );
    assert!(offset.abs() < 1e-9);
    assert!(f.points > 1000, "{} inliers", f.points);
    assert!(angle < 0.01, "normal error {angle} deg");
    assert!(dist.abs() < 0.01, "plane offset {dist} mm");
    // no stripe on an edge: every point near the true plane, not only the inliers
    assert!(worst < 0.03, "a point {worst} mm off the true plane");
}

/// FNV-1a (64 bit) of an 8-bit image's pixels.
fn fnv(img: &stripecal::model::image::AnyGray) -> u64 {
    let stripecal::model::image::AnyGray::U8(g) = img else {
        panic!("8-bit image expected");
    };
    g.data.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| {
        (h ^ b as u64).wrapping_mul(0x0100_0000_01b3)
    })
}

#[test]
fn default_renders_match_the_renders_before_the_artefacts() {
    // hp3-paper as it is: pixel hashes of images rendered before scene.rs learned
    // several spheres, the free plate and table-less scenes (calib view 0's laser image,
    // scan frame 40)
    let tw = Twin::new(SimConfig::hp3_paper()).unwrap();
    let q = tw.calibration_poses().unwrap()[0].q_deg.clone();
    let v = tw.render_view(&q, 0).unwrap();
    assert_eq!(fnv(v.laser_image.as_ref().unwrap()), 0x599d_c489_05bb_226f);
    let qs = tw.scan_poses().unwrap();
    let f = tw.render_scan_frame(&qs[40], 40).unwrap();
    assert_eq!(fnv(f.laser_image.as_ref().unwrap()), 0xd041_46a7_5efc_69e3);
}

#[test]
fn renders_without_verify_are_unchanged() {
    // verify off (the default): the same calibration view and truth as before the knobs
    let base = SimConfig::hp3_paper()
        .with_overrides(&serde_json::json!({"seed": 4, "poses": {"count": 3}}))
        .unwrap();
    let off = Twin::new(base.clone()).unwrap();
    let on = Twin::new(config(serde_json::json!({"scan": {"enabled": true}}))).unwrap();
    let poses = off.calibration_poses().unwrap();
    assert_eq!(poses, on.calibration_poses().unwrap());
    let q = &poses[1].q_deg;
    let a = off.render_view(q, 1).unwrap();
    let b = on.render_view(q, 1).unwrap();
    assert_eq!(a.board_image, b.board_image);
    assert_eq!(a.laser_image, b.laser_image);
    let qs = off.scan_poses().unwrap();
    let k = qs.len() / 2;
    let a = off.render_scan_frame(&qs[k], k).unwrap();
    let b = on.render_scan_frame(&qs[k], k).unwrap();
    assert_eq!(a.laser_image, b.laser_image);
    // truth.json's sim_config has no `verify` while it is off
    let t = off.truth(true);
    assert!(t.extra["sim_config"].get("verify").is_none());
    assert!(on.truth(true).extra["sim_config"].get("verify").is_some());
}
