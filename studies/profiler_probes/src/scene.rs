//! Synthetic sphere profiles: a copy of the generator of the core crate's profiler tests
//! (crates/stripecal/src/pipeline/profile/tests.rs, `scene`), so that the probes see the
//! same views as those tests.

use nalgebra::{Point3, Vector3};
use stripecal::model::geometry::{iso_from_parts, iso_from_rotvec, rotvec_to_matrix, Iso3};
use stripecal::model::{Profile, RobotReading};
use stripecal::numerics::rng::SplitMix64;
use stripecal::pipeline::profile::ProfileInput;

pub struct Scene {
    pub x: Iso3,
    pub centre: Vector3<f64>,
    pub diameter: f64,
    pub inputs: Vec<ProfileInput>,
}

/// `n` views of an 80 mm sphere on a table: stand-off 250-300 mm, the centre within
/// +-15 mm along the line, the plane 0.1-0.75 R from the centre on both sides (or the
/// coordinate `fixed` of the centre in the sensor frame held: 0 x, 1 y, 2 z); noise
/// `noise` mm, 1 % spikes of 0.5-3 mm.
pub fn scene(n: usize, seed: u64, noise: f64, fixed: Option<usize>) -> Scene {
    let x = iso_from_rotvec(
        &Vector3::new(0.05, 3.1, -0.1),
        &Vector3::new(12.0, -6.0, 110.0),
    );
    let centre = Vector3::new(650.0, 40.0, 80.0);
    let (diameter, r) = (80.0, 40.0);
    let table_z = centre.z - r - 30.0;
    let mut rng = SplitMix64(seed);
    let mut inputs = Vec::new();
    for i in 0..n {
        let side = if i % 2 == 0 { 1.0 } else { -1.0 };
        let mut p = Vector3::new(
            30.0 * (rng.uniform() - 0.5),
            side * r * (0.1 + 0.65 * rng.uniform()),
            250.0 + 50.0 * rng.uniform(),
        );
        match fixed {
            Some(0) => p.x = 3.0,
            Some(1) => p.y = 12.0,
            Some(2) => p.z = 270.0,
            _ => {}
        }
        // the sensor looks down (its z towards the base's -z), tilted up to ~20 deg
        let tilt = rotvec_to_matrix(&Vector3::new(
            0.35 * (rng.uniform() - 0.5),
            0.35 * (rng.uniform() - 0.5),
            1.5 * (rng.uniform() - 0.5),
        ));
        let down = rotvec_to_matrix(&Vector3::new(std::f64::consts::PI, 0.0, 0.0));
        let rot = down * tilt;
        let bs = iso_from_parts(&rot, &(centre - rot * p));
        let a = bs * x.inverse();
        // the table plane z_base = table_z in the sensor frame: n . s = d
        let sb = bs.inverse();
        let nrm = sb.rotation * Vector3::z();
        let d = nrm.dot(&(sb * Point3::new(0.0, 0.0, table_z)).coords);
        let mut pts = Vec::new();
        let mut xs = -45.0;
        while xs <= 45.0 {
            let mut z = f64::INFINITY;
            let disc = r * r - p.y * p.y - (xs - p.x).powi(2);
            if disc >= 0.0 {
                z = p.z - disc.sqrt();
            }
            if nrm.z.abs() > 1e-9 {
                let zt = (d - nrm.x * xs) / nrm.z;
                if zt > 0.0 && zt < z {
                    z = zt;
                }
            }
            if z.is_finite() && z < 400.0 {
                let mut zz = z + noise * rng.normal();
                if rng.uniform() < 0.01 {
                    zz +=
                        (0.5 + 2.5 * rng.uniform()) * if rng.uniform() < 0.5 { -1.0 } else { 1.0 };
                }
                pts.push([xs, zz]);
            }
            xs += 0.03;
        }
        inputs.push(ProfileInput {
            view: i,
            line: i + 2,
            file: format!("profiles/p{i:03}.csv"),
            profile: Profile {
                points: pts,
                gaps: 0,
            },
            reading: RobotReading::FlangePose(a),
        });
    }
    Scene {
        x,
        centre,
        diameter,
        inputs,
    }
}
