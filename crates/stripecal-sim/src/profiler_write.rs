//! Writing the profiler mode's dataset and scan ([`crate::profiler`],
//! [`crate::profiler_poses`]) in the files of spec/DATASET.md, "A profile dataset":
//!
//! - `OUT/calib/rig.json`: `"sensor": {"kind": "profiler", "invalid_z": ...}`,
//!   `"artefact": {"kind": "sphere", "diameter_mm": <declared or null>}` and, with
//!   `poses = "joints"`, the NOMINAL `robot`;
//! - `OUT/calib/views.csv`: header `profile,q1,...,qN` (or `profile,<pose columns>`),
//!   one row per view, `profiles/view_000.csv`...;
//! - `OUT/calib/profiles/view_NNN.csv`: header `x_mm,z_mm` (`,intensity` with
//!   `profiler.intensity`), 6 decimals, gaps as an empty z, `nan` or `invalid_z` in turn;
//! - `OUT/calib/truth.json` (`stripecal/truth@1`): `sensor.kind = "profiler"`, the true
//!   `hand_cam` (= `T_hand_sensor`), the true `robot` (joints only), the `sphere` (base
//!   frame), the `table` plane (`n . p = d`, base frame), the `stand`, the `profiler`
//!   knobs and per view (`views`) the profile file, the true readings, `base_hand`, the
//!   sphere centre in the sensor frame `sphere_center_sensor_mm`, the tilt and the
//!   point counts. No `camera`, `laser_plane` or `base_board`.
//! - `OUT/scan/`: `scan.csv` (header `profile,...` as views.csv), `profiles/scan_NNNN.csv`,
//!   rig.json and truth.json (the same keys, per frame under `frames`).
//!
//! Each folder is staged under a temporary name and renamed when complete; every file
//! is written with the core's atomic writer.

use std::path::{Path, PathBuf};

use serde_json::{json, Map, Value};

use stripecal::io;
use stripecal::Robot;

use crate::config::pose_cfg;
use crate::poses::PoseInfo;
use crate::profiler::{render_profile, Hit, ProfileSample, ProfilerCfg};
use crate::profiler_poses::ProfilerView;
use crate::rng::Rng;
use crate::{DatasetSummary, SimError, Twin};

/// First random stream of the calibration profiles (one per view).
const VIEW_STREAM: u64 = 0x7072_6f66_0000;
/// First random stream of the scan profiles (one per frame).
const SCAN_STREAM: u64 = 0x7072_7363_0000;

/// What one written profile holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ProfileCounts {
    /// Points written with a z (valid points, spikes included).
    pub points: usize,
    /// Of those: on the sphere, the table, the stand (by the surface hit).
    pub sphere: usize,
    pub table: usize,
    pub stand: usize,
    /// Points written as gaps (out of range, nothing hit, or dropped).
    pub gaps: usize,
    /// Of the gaps: random dropouts of valid points.
    pub dropouts: usize,
    /// Points with a spike.
    pub spikes: usize,
}

/// What the profiler mode wrote (in [`DatasetSummary::profiler`]).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ProfilerSummary {
    /// Per calibration view.
    pub views: Vec<ProfileCounts>,
    /// Per view: the sphere centre in the sensor frame, mm.
    pub centers_sensor_mm: Vec<[f64; 3]>,
    /// Per scan frame.
    pub scan: Vec<ProfileCounts>,
}

/// The text of a profile file and its counts (module docs). Gaps cycle through an empty
/// z, `nan` and `invalid_z` (`-inf` without one).
pub fn profile_csv(cfg: &ProfilerCfg, samples: &[ProfileSample]) -> (String, ProfileCounts) {
    let sentinel = cfg
        .invalid_z
        .map_or_else(|| "-inf".to_string(), |v| format!("{v}"));
    let gap_tokens = ["", "nan", sentinel.as_str()];
    let mut text = String::with_capacity(32 * samples.len() + 32);
    text.push_str(if cfg.intensity {
        "x_mm,z_mm,intensity\n"
    } else {
        "x_mm,z_mm\n"
    });
    let mut c = ProfileCounts::default();
    for s in samples {
        let z = match s.z_mm {
            Some(z) => {
                c.points += 1;
                match s.truth.map(|(_, h)| h) {
                    Some(Hit::Sphere) => c.sphere += 1,
                    Some(Hit::Table) => c.table += 1,
                    Some(Hit::Stand) => c.stand += 1,
                    None => {}
                }
                if s.spike_mm != 0.0 {
                    c.spikes += 1;
                }
                format!("{z:.6}")
            }
            None => {
                let tok = gap_tokens[c.gaps % 3].to_string();
                c.gaps += 1;
                if s.dropout {
                    c.dropouts += 1;
                }
                tok
            }
        };
        if cfg.intensity {
            text.push_str(&format!("{:.6},{z},{}\n", s.x_mm, s.intensity));
        } else {
            text.push_str(&format!("{:.6},{z}\n", s.x_mm));
        }
    }
    (text, c)
}

/// The JSON object of a robot (rig.json's form).
fn robot_json(r: &Robot) -> Value {
    let joints: Vec<Value> = r
        .joints
        .iter()
        .map(|j| {
            let mut m = Map::new();
            m.insert("theta0_deg".into(), json!(j.theta0_deg));
            m.insert("alpha_deg".into(), json!(j.alpha_deg));
            m.insert("a_mm".into(), json!(j.a_mm));
            m.insert("d_mm".into(), json!(j.d_mm));
            if j.beta_deg != 0.0 {
                m.insert("beta_deg".into(), json!(j.beta_deg));
            }
            Value::Object(m)
        })
        .collect();
    json!({"name": r.name, "joints": joints})
}

fn counts_json(c: &ProfileCounts) -> Value {
    json!({
        "points": c.points, "sphere": c.sphere, "table": c.table, "stand": c.stand,
        "gaps": c.gaps, "dropouts": c.dropouts, "spikes": c.spikes,
    })
}

fn write_json(path: &Path, v: &Value) -> Result<(), SimError> {
    let text = serde_json::to_string_pretty(v).map_err(|e| SimError::Render(e.to_string()))?;
    io::write_atomic(path, (text + "\n").as_bytes())?;
    Ok(())
}

/// An empty staging folder `out/.name.partial-<pid>` with an empty `profiles` folder.
fn staging(out: &Path, name: &str) -> Result<PathBuf, SimError> {
    let tmp = out.join(format!(".{name}.partial-{}", std::process::id()));
    if tmp.exists() {
        std::fs::remove_dir_all(&tmp).map_err(|e| stripecal::Error::io(&tmp, e))?;
    }
    let p = tmp.join("profiles");
    std::fs::create_dir_all(&p).map_err(|e| stripecal::Error::io(&p, e))?;
    Ok(tmp)
}

fn replace(tmp: &Path, target: &Path) -> Result<(), SimError> {
    if target.exists() {
        std::fs::remove_dir_all(target).map_err(|e| stripecal::Error::io(target, e))?;
    }
    std::fs::rename(tmp, target).map_err(|e| stripecal::Error::io(target, e))?;
    Ok(())
}

/// A profile folder's names: the folder, its table (views.csv or scan.csv), the
/// profiles' file stem, truth.json's key of the per-pose entries, and the first noise
/// stream of its profiles.
#[derive(Clone, Copy)]
struct ProfileFolder {
    name: &'static str,
    csv: &'static str,
    stem: &'static str,
    key: &'static str,
    stream: u64,
}

/// The calibration folder `calib`.
const CALIB_FOLDER: ProfileFolder = ProfileFolder {
    name: "calib",
    csv: "views.csv",
    stem: "view",
    key: "views",
    stream: VIEW_STREAM,
};

/// The scan folder `scan`.
const SCAN_FOLDER: ProfileFolder = ProfileFolder {
    name: "scan",
    csv: "scan.csv",
    stem: "scan",
    key: "frames",
    stream: SCAN_STREAM,
};

impl Twin {
    /// rig.json of the profiler mode (module docs).
    pub fn profiler_rig_json(&self) -> Value {
        let pc = &self.cfg.profiler;
        let mut sensor = json!({"kind": "profiler"});
        if let Some(v) = pc.invalid_z {
            sensor["invalid_z"] = json!(v);
        }
        let mut rig = json!({
            "format": "stripecal/rig@1",
            "sensor": sensor,
            "artefact": {"kind": "sphere", "diameter_mm": pc.declared_diameter()},
        });
        if pc.joints() {
            rig["robot"] = robot_json(&self.robot_nominal);
        }
        rig
    }

    /// The truth common to the dataset and the scan (module docs).
    pub fn profiler_truth_json(&self) -> Value {
        let pc = &self.cfg.profiler;
        let sc = self.profiler_scene();
        let mut t = json!({
            "format": "stripecal/truth@1",
            "sensor": {"kind": "profiler"},
            "hand_cam": pose_cfg(&self.hand_sensor()),
            "sphere": {"center_mm": [sc.center.x, sc.center.y, sc.center.z], "diameter_mm": pc.sphere_diameter_mm},
            "table": {"normal": [0.0, 0.0, 1.0], "d_mm": sc.table_z},
            "stand": {"diameter_mm": pc.stand_diameter_mm, "axis_xy_mm": [sc.center.x, sc.center.y]},
            "profiler": serde_json::to_value(pc).unwrap_or(Value::Null),
            "seed": self.cfg.seed,
        });
        if pc.joints() {
            t["robot"] = robot_json(&self.robot_true);
        }
        t
    }

    /// The views.csv / scan.csv header after `profile`.
    fn profiler_columns(&self) -> Result<Vec<String>, SimError> {
        Ok(if self.cfg.profiler.joints() {
            (1..=self.robot_nominal.dof())
                .map(|i| format!("q{i}"))
                .collect()
        } else {
            let pc = self.cfg.profiler.pose_columns_model()?;
            pc.names().iter().map(|s| s.to_string()).collect()
        })
    }

    /// The reading cells of a row: the joint readings, or the flange pose the controller
    /// reports (the NOMINAL robot's forward kinematics of them).
    fn profiler_reading(&self, q: &[f64]) -> Result<Vec<String>, SimError> {
        Ok(if self.cfg.profiler.joints() {
            q.iter().map(|v| format!("{v}")).collect()
        } else {
            let pc = self.cfg.profiler.pose_columns_model()?;
            let t = self.robot_nominal.forward(q)?;
            pc.to_values(&t).iter().map(|v| format!("{v}")).collect()
        })
    }

    /// The profile of pose `v` with its noise stream `stream` (`None`: noise-free).
    pub fn profiler_profile(&self, v: &ProfilerView, stream: Option<u64>) -> Vec<ProfileSample> {
        let mut rng = stream.map(|s| Rng::new(self.cfg.seed, s));
        render_profile(
            &self.cfg.profiler,
            &self.profiler_scene(),
            &v.base_sensor,
            rng.as_mut(),
        )
    }

    /// Writes the poses `views` as the folder `out/name`: `csv` (views.csv or scan.csv),
    /// `profiles/<stem>_NNN.csv`, rig.json and truth.json with per pose entries under
    /// `key` (the names of `folder`); returns the folder and the counts.
    fn write_profiles(
        &self,
        out: &Path,
        folder: &ProfileFolder,
        views: &[ProfilerView],
        progress: &mut dyn FnMut(&str, usize, usize),
    ) -> Result<(PathBuf, Vec<ProfileCounts>), SimError> {
        let ProfileFolder {
            name,
            csv,
            stem,
            key,
            stream,
        } = *folder;
        let stage = format!("profiler {name}");
        let tmp = staging(out, name)?;
        let cols = self.profiler_columns()?;
        let mut table = format!("profile,{}\n", cols.join(","));
        let mut entries = Vec::with_capacity(views.len());
        let mut counts = Vec::with_capacity(views.len());
        // views: at most MAX_VIEWS (3 digits); scans: 4 (wider when longer)
        let digits = if stem == "scan" { 4 } else { 3 };
        for (i, v) in views.iter().enumerate() {
            progress(&stage, i, views.len());
            let file = format!("profiles/{stem}_{i:0digits$}.csv");
            let samples = self.profiler_profile(v, Some(stream.wrapping_add(i as u64)));
            let (text, c) = profile_csv(&self.cfg.profiler, &samples);
            io::write_atomic(tmp.join(&file), text.as_bytes())?;
            table.push_str(&format!(
                "{file},{}\n",
                self.profiler_reading(&v.q_deg)?.join(",")
            ));
            let cs = v.center_sensor;
            entries.push(json!({
                "profile": file,
                "q_deg": v.q_deg,
                "base_hand": pose_cfg(&v.base_hand),
                "sphere_center_sensor_mm": [cs.x, cs.y, cs.z],
                "tilt_deg": v.tilt_deg,
                "points": counts_json(&c),
            }));
            counts.push(c);
        }
        progress(&stage, views.len(), views.len());
        io::write_atomic(tmp.join(csv), table.as_bytes())?;
        write_json(&tmp.join("rig.json"), &self.profiler_rig_json())?;
        let mut truth = self.profiler_truth_json();
        truth[key] = Value::Array(entries);
        write_json(&tmp.join("truth.json"), &truth)?;
        let dir = out.join(name);
        replace(&tmp, &dir)?;
        Ok((dir, counts))
    }

    /// Writes the profiler dataset `out/calib` and, with `scan_frames > 0`, the scan
    /// `out/scan` (module docs).
    pub fn write_profiler(
        &self,
        out: &Path,
        progress: &mut dyn FnMut(&str, usize, usize),
    ) -> Result<DatasetSummary, SimError> {
        std::fs::create_dir_all(out).map_err(|e| stripecal::Error::io(out, e))?;
        let views = self.profiler_views()?;
        let (calib_dir, counts) = self.write_profiles(out, &CALIB_FOLDER, &views, progress)?;
        let r = self.cfg.profiler.radius();
        let infos = views
            .iter()
            .map(|v| PoseInfo {
                q_deg: v.q_deg.clone(),
                standoff_mm: v.center_sensor.z,
                tilt_deg: v.tilt_deg,
                stripe_chord_mm: 2.0 * (r * r - v.center_sensor.y.powi(2)).max(0.0).sqrt(),
            })
            .collect();
        let scan = self.profiler_scan()?;
        let (scan_dir, scan_counts) = if scan.is_empty() {
            (None, vec![])
        } else {
            let (d, c) = self.write_profiles(out, &SCAN_FOLDER, &scan, progress)?;
            (Some(d), c)
        };
        Ok(DatasetSummary {
            calib_dir,
            scan_dir,
            views: infos,
            view_circles: vec![0; views.len()],
            view_stripe_points: counts.iter().map(|c| c.sphere).collect(),
            scan_frames: scan.len(),
            scan_sphere_points: scan_counts.iter().map(|c| c.sphere).sum(),
            table_dir: None,
            table_frames: 0,
            verify_dir: None,
            verify_frames: 0,
            direction: self.direction,
            profiler: Some(ProfilerSummary {
                views: counts,
                centers_sensor_mm: views
                    .iter()
                    .map(|v| [v.center_sensor.x, v.center_sensor.y, v.center_sensor.z])
                    .collect(),
                scan: scan_counts,
            }),
        })
    }
}

impl Twin {
    /// The calibration views as the profiler calibration reads them, in memory (no
    /// files): each view's profile (gaps skipped and counted, as a reader would) with its
    /// joint readings, and the rig (the NOMINAL robot, the declared diameter) — for tests
    /// and benchmarks that skip the files.
    pub fn profiler_inputs(
        &self,
    ) -> Result<
        (
            Vec<stripecal::pipeline::profile::ProfileInput>,
            stripecal::model::ProfileRig,
        ),
        SimError,
    > {
        use stripecal::model::{Profile, RobotReading};
        let inputs = self
            .profiler_views()?
            .iter()
            .enumerate()
            .map(|(i, v)| {
                let samples = self.profiler_profile(v, Some(VIEW_STREAM.wrapping_add(i as u64)));
                let points: Vec<[f64; 2]> = samples
                    .iter()
                    .filter_map(|s| s.z_mm.map(|z| [s.x_mm, z]))
                    .collect();
                stripecal::pipeline::profile::ProfileInput {
                    view: i,
                    line: i + 2,
                    file: format!("profiles/view_{i:03}.csv"),
                    profile: Profile {
                        gaps: samples.len() - points.len(),
                        points,
                    },
                    reading: RobotReading::Joints(v.q_deg.clone()),
                }
            })
            .collect();
        let rig = stripecal::model::ProfileRig {
            robot: Some(self.cfg.robot_nominal()?),
            invalid_z: self.cfg.profiler.invalid_z,
            diameter_mm: self.cfg.profiler.declared_diameter(),
        };
        Ok((inputs, rig))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Point3, Vector3};
    use stripecal::model::geometry::iso_from_rotvec;
    use stripecal::DhJoint;

    use crate::SimConfig;

    fn twin(over: Value) -> Twin {
        let c = SimConfig::preset("hp3-profiler")
            .unwrap()
            .with_overrides(&over)
            .unwrap();
        Twin::new(c).unwrap()
    }

    /// A tiny CSV reader: the header and the rows, cells split at commas.
    fn read_csv(p: &Path) -> (Vec<String>, Vec<Vec<String>>) {
        let text = std::fs::read_to_string(p).unwrap();
        let mut lines = text.lines();
        let split = |l: &str| l.split(',').map(str::to_string).collect::<Vec<_>>();
        let head = split(lines.next().unwrap());
        (head, lines.map(split).collect())
    }

    fn read_json(p: &Path) -> Value {
        serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
    }

    fn vec3(v: &Value) -> Vector3<f64> {
        Vector3::new(
            v[0].as_f64().unwrap(),
            v[1].as_f64().unwrap(),
            v[2].as_f64().unwrap(),
        )
    }

    /// The true robot and `T_hand_sensor` as truth.json gives them.
    fn truth_model(t: &Value) -> (Robot, stripecal::model::geometry::Iso3) {
        let joints = t["robot"]["joints"]
            .as_array()
            .unwrap()
            .iter()
            .map(|j| DhJoint {
                theta0_deg: j["theta0_deg"].as_f64().unwrap(),
                alpha_deg: j["alpha_deg"].as_f64().unwrap(),
                a_mm: j["a_mm"].as_f64().unwrap(),
                d_mm: j["d_mm"].as_f64().unwrap(),
                beta_deg: j["beta_deg"].as_f64().unwrap_or(0.0),
            })
            .collect();
        let robot = Robot::new(t["robot"]["name"].as_str().unwrap(), joints).unwrap();
        let h = &t["hand_cam"];
        (
            robot,
            iso_from_rotvec(&vec3(&h["rotation_vector"]), &vec3(&h["translation_mm"])),
        )
    }

    #[test]
    fn noise_free_points_lie_on_the_true_surfaces() {
        let dir = tempfile::tempdir().unwrap();
        let t = twin(json!({
            "robot_error": {"theta0_deg": 0.05, "a_mm": 0.3, "d_mm": 0.3, "alpha_deg": 0.02},
            "profiler": {"noise_z_mm": 0.0, "gap_fraction": 0.0, "spike_fraction": 0.0, "scan_frames": 0}
        }));
        let s = t.write(dir.path(), &mut |_, _, _| {}).unwrap();
        let calib = dir.path().join("calib");
        let truth = read_json(&calib.join("truth.json"));
        let (robot, hs) = truth_model(&truth);
        assert_ne!(
            robot, t.robot_nominal,
            "the true robot differs from rig.json's"
        );
        let c = vec3(&truth["sphere"]["center_mm"]);
        let r = 0.5 * truth["sphere"]["diameter_mm"].as_f64().unwrap();
        let table_z = truth["table"]["d_mm"].as_f64().unwrap();
        let (head, rows) = read_csv(&calib.join("views.csv"));
        assert_eq!(head, ["profile", "q1", "q2", "q3", "q4", "q5", "q6"]);
        let views = t.profiler_views().unwrap();
        let (mut worst_mem, mut worst_file, mut table_worst) = (0.0f64, 0.0f64, 0.0f64);
        let (mut n_sphere, mut n_table) = (0, 0);
        for (i, row) in rows.iter().enumerate() {
            let q: Vec<f64> = row[1..].iter().map(|x| x.parse().unwrap()).collect();
            let base_sensor = robot.forward(&q).unwrap() * hs;
            // in memory: exact
            for smp in t.profiler_profile(&views[i], None) {
                let Some((z, h)) = smp.truth else { continue };
                let p = (base_sensor * Point3::new(smp.x_mm, 0.0, z)).coords;
                match h {
                    Hit::Sphere => {
                        worst_mem = worst_mem.max(((p - c).norm() - r).abs());
                        n_sphere += 1;
                    }
                    Hit::Table => {
                        table_worst = table_worst.max((p.z - table_z).abs());
                        n_table += 1;
                    }
                    Hit::Stand => {
                        let rad = ((p.x - c.x).powi(2) + (p.y - c.y).powi(2)).sqrt();
                        assert!(
                            (rad - 0.5 * truth["stand"]["diameter_mm"].as_f64().unwrap()).abs()
                                < 1e-9
                                && p.z <= c.z
                                && p.z >= table_z
                        );
                    }
                }
            }
            // from the file (6 decimals): every point near the sphere centre is on it
            let (ph, pts) = read_csv(&calib.join(&row[0]));
            assert_eq!(ph, ["x_mm", "z_mm", "intensity"]);
            assert_eq!(pts.len(), 3000);
            for p in &pts {
                let Ok(z) = p[1].parse::<f64>() else { continue };
                if !z.is_finite() {
                    continue;
                }
                let b = (base_sensor * Point3::new(p[0].parse().unwrap(), 0.0, z)).coords;
                let d = (b - c).norm() - r;
                if d.abs() < 0.1 {
                    worst_file = worst_file.max(d.abs());
                }
            }
            assert_eq!(s.profiler.as_ref().unwrap().views[i].spikes, 0);
        }
        assert!(
            worst_mem < 1e-9,
            "sphere points off the sphere by {worst_mem} mm"
        );
        assert!(
            table_worst < 1e-9,
            "table points off the table by {table_worst} mm"
        );
        assert!(
            worst_file < 2e-6,
            "written points off the sphere by {worst_file} mm"
        );
        assert!(
            n_sphere > 15 * 500 && n_table > 15 * 100,
            "{n_sphere} {n_table}"
        );
    }

    #[test]
    fn gaps_and_spikes_follow_their_fractions() {
        let t = twin(json!({"profiler": {"spike_fraction": 0.02, "gap_fraction": 0.05}}));
        let pc = &t.cfg.profiler;
        let views = t.profiler_views().unwrap();
        let (mut valid, mut drops, mut kept, mut spikes) = (0usize, 0usize, 0usize, 0usize);
        let (mut res2, mut nres) = (0.0, 0usize);
        for (i, v) in views.iter().enumerate() {
            let clean = t.profiler_profile(v, None);
            let noisy = t.profiler_profile(v, Some(VIEW_STREAM + i as u64));
            for (a, b) in clean.iter().zip(&noisy) {
                assert_eq!(a.truth, b.truth);
                let Some((z, _)) = a.truth else {
                    assert!(b.z_mm.is_none());
                    continue;
                };
                valid += 1;
                match b.z_mm {
                    None => drops += 1,
                    Some(zn) => {
                        kept += 1;
                        let e = zn - z;
                        if e.abs() > 0.3 {
                            spikes += 1;
                            assert!(
                                e.abs() >= pc.spike_min_mm - 0.1
                                    && e.abs() <= pc.spike_max_mm + 0.1
                            );
                        } else {
                            res2 += e * e;
                            nres += 1;
                        }
                    }
                }
            }
        }
        let bound = |n: usize, p: f64, k: usize| {
            let (m, sd) = (n as f64 * p, (n as f64 * p * (1.0 - p)).sqrt());
            assert!((k as f64 - m).abs() < 5.0 * sd, "{k} vs {m} +- {sd}");
        };
        bound(valid, pc.gap_fraction, drops);
        bound(kept, pc.spike_fraction, spikes);
        let sd = (res2 / nres as f64).sqrt();
        assert!((sd / pc.noise_z_mm - 1.0).abs() < 0.05, "noise sd {sd}");
    }

    #[test]
    fn files_follow_the_contract() {
        let dir = tempfile::tempdir().unwrap();
        let t =
            twin(json!({"profiler": {"views": 4, "scan_frames": 5, "diameter_declared": false}}));
        let s = t.write(dir.path(), &mut |_, _, _| {}).unwrap();
        let calib = dir.path().join("calib");
        let rig = read_json(&calib.join("rig.json"));
        assert_eq!(rig["format"], "stripecal/rig@1");
        assert_eq!(
            rig["sensor"],
            json!({"kind": "profiler", "invalid_z": -99999.9999})
        );
        assert_eq!(
            rig["artefact"],
            json!({"kind": "sphere", "diameter_mm": null})
        );
        assert_eq!(rig["robot"]["joints"].as_array().unwrap().len(), 6);
        assert_eq!(rig["robot"]["joints"][1]["theta0_deg"], 90.0, "nominal HP3");
        let (_, rows) = read_csv(&calib.join("views.csv"));
        assert_eq!(rows.len(), 4);
        let mut tokens = std::collections::BTreeSet::new();
        let mut gaps = 0;
        for (i, row) in rows.iter().enumerate() {
            assert_eq!(row[0], format!("profiles/view_{i:03}.csv"));
            let (_, pts) = read_csv(&calib.join(&row[0]));
            for p in &pts {
                assert_eq!(p.len(), 3);
                assert!(p[0].parse::<f64>().unwrap().is_finite());
                match p[1].parse::<f64>() {
                    Ok(z) if z.is_finite() && z != -99999.9999 => {
                        assert!(z > 140.0 && z < 360.0, "{z}");
                        assert_eq!(p[1].split('.').nth(1).unwrap().len(), 6);
                    }
                    _ => {
                        tokens.insert(p[1].clone());
                        gaps += 1;
                    }
                }
            }
        }
        let want: std::collections::BTreeSet<String> = ["", "nan", "-99999.9999"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        assert_eq!(tokens, want);
        let ps = s.profiler.as_ref().unwrap();
        assert_eq!(gaps, ps.views.iter().map(|c| c.gaps).sum::<usize>());
        let truth = read_json(&calib.join("truth.json"));
        assert_eq!(truth["sensor"]["kind"], "profiler");
        assert!(truth.get("camera").is_none() && truth.get("laser_plane").is_none());
        let tv = truth["views"].as_array().unwrap();
        assert_eq!(tv.len(), 4);
        for (v, c) in tv.iter().zip(&ps.centers_sensor_mm) {
            assert!((vec3(&v["sphere_center_sensor_mm"]) - Vector3::from(*c)).norm() < 1e-12);
        }
        // the scan
        let scan = dir.path().join("scan");
        let (sh, srows) = read_csv(&scan.join("scan.csv"));
        assert_eq!(sh[0], "profile");
        assert_eq!(srows.len(), 5);
        assert!(scan.join("profiles/scan_0004.csv").exists());
        assert_eq!(
            read_json(&scan.join("truth.json"))["frames"]
                .as_array()
                .unwrap()
                .len(),
            5
        );
        assert_eq!(s.scan_frames, 5);
    }

    #[test]
    fn scan_points_lie_on_the_sphere_and_the_camera_truth_is_unchanged() {
        let t =
            twin(json!({"profiler": {"noise_z_mm": 0.0, "scan_frames": 9, "scan_step_mm": 7.0}}));
        let sc = t.profiler_scene();
        let scan = t.profiler_scan().unwrap();
        let mut worst = 0.0f64;
        let mut on_sphere = 0;
        for v in &scan {
            let bs = t.robot_true.forward(&v.q_deg).unwrap() * t.hand_sensor();
            for s in t.profiler_profile(v, None) {
                if let Some((z, Hit::Sphere)) = s.truth {
                    let p = (bs * Point3::new(s.x_mm, 0.0, z)).coords;
                    worst = worst.max(((p - sc.center).norm() - sc.radius).abs());
                    on_sphere += 1;
                }
            }
        }
        assert!(worst < 1e-9 && on_sphere > 9 * 1000, "{worst} {on_sphere}");
        // the camera twin's truth.json does not mention the profiler while it is off
        let cam = Twin::new(SimConfig::preset("hp3-paper").unwrap()).unwrap();
        assert!(cam.truth(false).extra["sim_config"]
            .get("profiler")
            .is_none());
        assert!(t.truth(false).extra["sim_config"].get("profiler").is_some());
    }

    #[test]
    fn a_tall_stand_is_seen_on_its_cylinder() {
        let t = twin(json!({"profiler": {
            "noise_z_mm": 0.0, "stand_height_mm": 130.0, "z_max_mm": 500.0,
            "tilt_min_deg": 25.0, "tilt_max_deg": 35.0, "scan_frames": 0
        }}));
        let sc = t.profiler_scene();
        let mut stand = 0;
        for v in t.profiler_views().unwrap() {
            let bs = t.robot_true.forward(&v.q_deg).unwrap() * t.hand_sensor();
            for s in t.profiler_profile(&v, None) {
                if let Some((z, Hit::Stand)) = s.truth {
                    let p = (bs * Point3::new(s.x_mm, 0.0, z)).coords;
                    let rad = ((p.x - sc.center.x).powi(2) + (p.y - sc.center.y).powi(2)).sqrt();
                    assert!((rad - sc.stand_radius).abs() < 1e-9, "{rad}");
                    assert!(p.z >= sc.table_z - 1e-9 && p.z <= sc.center.z - sc.radius + 1e-9);
                    stand += 1;
                }
            }
        }
        assert!(stand > 50, "stand points: {stand}");
    }

    #[test]
    fn flange_poses_replace_the_joints() {
        let dir = tempfile::tempdir().unwrap();
        let t = twin(json!({"profiler": {"views": 3, "scan_frames": 0, "poses": "flange"}}));
        t.write(dir.path(), &mut |_, _, _| {}).unwrap();
        let calib = dir.path().join("calib");
        let rig = read_json(&calib.join("rig.json"));
        assert!(rig.get("robot").is_none());
        let (head, rows) = read_csv(&calib.join("views.csv"));
        assert_eq!(
            head,
            ["profile", "x_mm", "y_mm", "z_mm", "qw", "qx", "qy", "qz"]
        );
        let truth = read_json(&calib.join("truth.json"));
        assert!(truth.get("robot").is_none());
        let pc = io::PoseColumns::from_spec(&["quaternion"]).unwrap();
        for (row, v) in rows.iter().zip(truth["views"].as_array().unwrap()) {
            let vals: Vec<f64> = row[1..].iter().map(|x| x.parse().unwrap()).collect();
            let bh = pc.to_iso(&vals).unwrap();
            let b = &v["base_hand"];
            let want = iso_from_rotvec(&vec3(&b["rotation_vector"]), &vec3(&b["translation_mm"]));
            assert!((bh.translation.vector - want.translation.vector).norm() < 1e-9);
            assert!(bh.rotation.angle_to(&want.rotation) < 1e-12);
        }
        assert!(!dir.path().join("scan").exists());
    }
}
