//! A calibration whose cancellation flag is set returns `Error::Cancelled` and nothing
//! else, from the images (the detection's check) and from observations (the stages'
//! check); the same inputs with a flag nobody set calibrate. Ctrl-C in Python sets the
//! flag (the binding's `detach_cancellable`; tests/test_scan_faults.py sends SIGINT).

use stripecal::pipeline::{calibrate_dataset, calibrate_observations, CalibrateOptions};
use stripecal::{Cancel, Error};
use stripecal_sim::{SimConfig, Twin};

fn twin() -> Twin {
    let cfg = SimConfig::hp3_paper()
        .with_overrides(&serde_json::json!({
            "camera": {"width": 384, "height": 288, "fu": 635.825, "fv": 661.26,
                       "u0": 172.82, "v0": 131.05},
            "poses": {"count": 4}, "seed": 11, "scan": {"enabled": false}
        }))
        .unwrap();
    Twin::new(cfg).unwrap()
}

#[test]
fn a_cancelled_calibration_returns_cancelled_and_an_unset_flag_changes_nothing() {
    let t = twin();
    let (views, rig) = (t.exact_observations().unwrap(), t.rig().unwrap());
    let cancel = Cancel::new();
    let opts = CalibrateOptions {
        cancel: cancel.clone(),
        leave_one_out: false,
        ..Default::default()
    };
    assert!(calibrate_observations(&views, &rig, &opts).is_ok());
    cancel.cancel();
    let r = calibrate_observations(&views, &rig, &opts);
    assert!(matches!(r, Err(Error::Cancelled)), "{:?}", r.err());

    let dir = tempfile::tempdir().unwrap();
    t.write(dir.path(), &mut |_, _, _| {}).unwrap();
    let r = calibrate_dataset(dir.path().join("calib"), &opts);
    assert!(matches!(r, Err(Error::Cancelled)), "{:?}", r.err());
}
