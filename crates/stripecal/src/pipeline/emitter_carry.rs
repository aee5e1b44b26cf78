//! The laser emitter's position, estimated on a measured sphere, carried back into the
//! calibration's board stripe-bias correction.
//!
//! ## Why
//!
//! The board's stripe-bias correction ([`super::board_stripe`]) needs the emitter, which
//! no calibration image locates: it assumes it at the plane's point nearest the camera,
//! `n d`, and puts the emitter anywhere within `+-range` (30 mm) of it along the plane's
//! two in-plane axes into the calibration's covariance, from the calibration's changes
//! with the emitter at the ends of each range (`d_+`, `d_-`; each axis adds
//! `(d_+ d_+^T + d_- d_-^T) / 6`). On the paper's twin, whose emitter is where the
//! calibration assumes it, that term takes the ball centre z's calibration part from
//! 0.305 to 0.375 um and x's from 0.196 to 0.268 um (means over 16 seeds). A sphere scan locates the emitter from the
//! stripe's brightness ([`crate::reconstruct::fit::stripe_bias`]'s estimate), so a
//! measurement of a sphere knows more than the calibration did.
//!
//! ## What is done
//!
//! calibration.json's `board_stripe_bias.emitter_response` keeps the response
//! ([`EmitterResponse`]: `n d`, the two axes, the range, the changes `d_+`, `d_-` per axis
//! over the covariance's numbers, and the covariance's trace when they were added). With
//! the emitter's estimate at in-plane offset `x_k` from `n d` and standard uncertainty
//! `s_k` (at least [`EMITTER_SD_FLOOR_MM`]) on axis `k`, the response is read as the
//! quadratic through `(-R, d_-)`, `(0, 0)`, `(R, d_+)`:
//! `D_k(x) = a_k x + b_k x^2`, `a_k = (d_+ - d_-) / (2R)`, `b_k = (d_+ + d_-) / (2R^2)`;
//! the measurement's numbers move by `sum_k D_k(x_k)` (each quantity by its calibration
//! gradient times that: first order, the moves are tenths of a micrometre) and the
//! covariance's range term is replaced by `sum_k g_k g_k^T s_k^2`, `g_k = a_k + 2 b_k x_k`.
//!
//! The response is applied only inside the range it was computed over (`|x_k| <= R`),
//! when the covariance is still the one it was added to (its trace agrees), and when
//! the measurement keeps the calibration's part; otherwise the calibration is used as it
//! is and the report says why ([`CarryInfo::reason`]).
//!
//! The floor: the brightness estimate neglects vignetting and the sheet's power along the
//! line; on the twin it lands 0.3-1.1 mm from the truth with standard uncertainties
//! 0.08-0.2 mm on a 45 mm ball (too small by up to 14 times), so no estimate is taken as
//! better than 5 mm, a sixth of the assumed range (the range term's standard uncertainty
//! drops from 17 mm to 5 mm).

use nalgebra::{DMatrix, DVector, Vector3};
use serde_json::{json, Value};

use crate::error::{Error, Result};
use crate::model::Calibration;

/// The smallest standard uncertainty an emitter estimate is taken with, mm (module
/// docs).
pub const EMITTER_SD_FLOOR_MM: f64 = 5.0;

/// The calibration's response to the emitter's position (module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct EmitterResponse {
    /// The assumed emitter, `n d`, camera frame, mm.
    pub origin_cam_mm: Vector3<f64>,
    /// The plane's two in-plane axes, camera frame.
    pub axes_cam: [Vector3<f64>; 2],
    /// The half range `R`, mm.
    pub range_mm: f64,
    /// The covariance's numbers the changes are over.
    pub parameters: Vec<String>,
    /// The changes with the emitter at `+R` and `-R` along each axis.
    pub plus: [DVector<f64>; 2],
    pub minus: [DVector<f64>; 2],
    /// The trace of the covariance the range term was added to.
    pub covariance_trace: f64,
}

/// A sphere's emitter estimate: camera frame, mm, its standard uncertainties along the
/// sphere model's two in-plane axes, and those axes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EmitterSample {
    pub emitter_cam_mm: Vector3<f64>,
    pub sd_mm: [f64; 2],
    pub basis: [Vector3<f64>; 2],
}

/// What carrying an emitter estimate did to a measurement.
#[derive(Debug, Clone, PartialEq)]
pub struct CarryInfo {
    /// The estimate's in-plane offsets from the calibration's assumed emitter, mm.
    pub offset_mm: [f64; 2],
    /// Their standard uncertainties as used (floored), mm.
    pub sd_mm: [f64; 2],
    /// Why it was not applied (`None`: applied).
    pub reason: Option<String>,
}

/// The calibration as a measurement uses it after an emitter estimate: the move of its
/// numbers and their covariance, both over the measurement's numbers.
#[derive(Debug, Clone)]
pub struct Carried {
    pub shift: DVector<f64>,
    pub covariance: DMatrix<f64>,
}

impl EmitterResponse {
    /// calibration.json's `board_stripe_bias.emitter_response`.
    pub fn to_json(&self) -> Value {
        let v3 = |v: &Vector3<f64>| json!([v.x, v.y, v.z]);
        let vs = |v: &[DVector<f64>; 2]| json!([v[0].as_slice(), v[1].as_slice()]);
        json!({"origin_cam_mm": v3(&self.origin_cam_mm),
               "axes_cam": [v3(&self.axes_cam[0]), v3(&self.axes_cam[1])],
               "range_mm": self.range_mm, "parameters": self.parameters,
               "plus": vs(&self.plus), "minus": vs(&self.minus),
               "covariance_trace": self.covariance_trace})
    }

    /// The response a calibration holds (`None`: it holds none: no board correction, or
    /// a file written before it was kept). A malformed one is an error naming the key.
    pub fn of(calibration: &Calibration) -> Result<Option<EmitterResponse>> {
        let Some(v) = calibration
            .extra
            .get("board_stripe_bias")
            .and_then(|b| b.get("emitter_response"))
        else {
            return Ok(None);
        };
        let bad = |what: &str| {
            Error::InvalidInput(format!(
                "calibration board_stripe_bias.emitter_response: {what}"
            ))
        };
        let num = |v: &Value, what: &str| v.as_f64().ok_or_else(|| bad(what));
        let vec3 = |v: &Value, what: &str| -> Result<Vector3<f64>> {
            let a = v
                .as_array()
                .filter(|a| a.len() == 3)
                .ok_or_else(|| bad(what))?;
            Ok(Vector3::new(
                num(&a[0], what)?,
                num(&a[1], what)?,
                num(&a[2], what)?,
            ))
        };
        let parameters: Vec<String> = v
            .get("parameters")
            .and_then(Value::as_array)
            .ok_or_else(|| bad("no \"parameters\""))?
            .iter()
            .map(|p| {
                p.as_str()
                    .map(String::from)
                    .ok_or_else(|| bad("a parameter name is not a string"))
            })
            .collect::<Result<_>>()?;
        let pair = |key: &str| -> Result<[DVector<f64>; 2]> {
            let a = v
                .get(key)
                .and_then(Value::as_array)
                .filter(|a| a.len() == 2)
                .ok_or_else(|| bad(&format!("\"{key}\" must hold two lists")))?;
            let one = |x: &Value| -> Result<DVector<f64>> {
                let l = x
                    .as_array()
                    .filter(|l| l.len() == parameters.len())
                    .ok_or_else(|| {
                        bad(&format!(
                            "\"{key}\" lists must have one number per parameter ({})",
                            parameters.len()
                        ))
                    })?;
                let n: Vec<f64> = l.iter().map(|e| num(e, key)).collect::<Result<_>>()?;
                Ok(DVector::from_vec(n))
            };
            Ok([one(&a[0])?, one(&a[1])?])
        };
        let axes = v
            .get("axes_cam")
            .and_then(Value::as_array)
            .filter(|a| a.len() == 2)
            .ok_or_else(|| bad("\"axes_cam\" must hold two vectors"))?;
        let r = EmitterResponse {
            origin_cam_mm: vec3(
                v.get("origin_cam_mm").unwrap_or(&Value::Null),
                "origin_cam_mm",
            )?,
            axes_cam: [vec3(&axes[0], "axes_cam")?, vec3(&axes[1], "axes_cam")?],
            range_mm: num(v.get("range_mm").unwrap_or(&Value::Null), "range_mm")?,
            plus: pair("plus")?,
            minus: pair("minus")?,
            covariance_trace: num(
                v.get("covariance_trace").unwrap_or(&Value::Null),
                "covariance_trace",
            )?,
            parameters,
        };
        if !(r.range_mm.is_finite() && r.range_mm > 0.0) {
            return Err(bad("\"range_mm\" must be positive"));
        }
        Ok(Some(r))
    }

    /// An estimate as offsets along this response's axes and their standard
    /// uncertainties (floored).
    pub fn offsets(&self, e: &EmitterSample) -> ([f64; 2], [f64; 2]) {
        let (sd_mm, basis) = (e.sd_mm, e.basis);
        let d = e.emitter_cam_mm - self.origin_cam_mm;
        let x = [d.dot(&self.axes_cam[0]), d.dot(&self.axes_cam[1])];
        let sd = std::array::from_fn(|k| {
            let v: f64 = (0..2)
                .map(|j| (self.axes_cam[k].dot(&basis[j]) * sd_mm[j]).powi(2))
                .sum();
            v.sqrt().max(EMITTER_SD_FLOOR_MM)
        });
        (x, sd)
    }

    /// The calibration over the measurement's numbers `names` (covariance `cov`, from
    /// `calibration`) with the emitter at offsets `x` (standard uncertainties `sd`);
    /// `Err(reason)` where it does not apply (module docs).
    pub fn carry(
        &self,
        calibration: &Calibration,
        names: &[String],
        cov: &DMatrix<f64>,
        x: [f64; 2],
        sd: [f64; 2],
    ) -> std::result::Result<Carried, String> {
        if names.is_empty() {
            return Err("the measurement leaves the calibration's part out".into());
        }
        let Some(named) = calibration.covariance.as_ref() else {
            return Err("the calibration has no covariance".into());
        };
        let trace = named.matrix.trace();
        if (trace - self.covariance_trace).abs() > 1e-9 * self.covariance_trace.abs().max(1e-300) {
            return Err(
                "the calibration's covariance is not the one the response was added to".into(),
            );
        }
        if let Some(k) = (0..2).find(|&k| x[k].abs() > self.range_mm) {
            return Err(format!(
                "the estimate is {:.1} mm from the assumed emitter along axis {}, outside the \
                 +-{:.0} mm the calibration covered",
                x[k],
                k + 1,
                self.range_mm
            ));
        }
        // The response's numbers in the measurement's order (names it lacks move no point).
        let idx: Vec<Option<usize>> = names
            .iter()
            .map(|n| self.parameters.iter().position(|p| p == n))
            .collect();
        let pick = |v: &DVector<f64>| {
            DVector::from_iterator(names.len(), idx.iter().map(|i| i.map_or(0.0, |i| v[i])))
        };
        let r = self.range_mm;
        let mut shift = DVector::zeros(names.len());
        let mut covariance = cov.clone();
        for k in 0..2 {
            let (p, m) = (pick(&self.plus[k]), pick(&self.minus[k]));
            let a = (&p - &m) / (2.0 * r);
            let b = (&p + &m) / (2.0 * r * r);
            shift += &a * x[k] + &b * (x[k] * x[k]);
            let g = &a + &b * (2.0 * x[k]);
            covariance -= (&p * p.transpose() + &m * m.transpose()) / 6.0;
            covariance += &g * g.transpose() * (sd[k] * sd[k]);
        }
        Ok(Carried { shift, covariance })
    }
}

impl CarryInfo {
    /// The measurement JSON's `calibration_emitter`.
    pub fn to_json(&self) -> Value {
        json!({"offset_mm": self.offset_mm, "sd_mm": self.sd_mm,
               "applied": self.reason.is_none(), "reason": self.reason})
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::NamedCovariance;

    fn response(names: &[&str], cov: &DMatrix<f64>) -> EmitterResponse {
        EmitterResponse {
            origin_cam_mm: Vector3::new(0.0, 0.0, 100.0),
            axes_cam: [Vector3::x(), Vector3::y()],
            range_mm: 30.0,
            parameters: names.iter().map(|s| s.to_string()).collect(),
            plus: [
                DVector::from_vec(vec![3.0, 1.0, 0.5]),
                DVector::from_vec(vec![0.0, 2.0, 0.0]),
            ],
            minus: [
                DVector::from_vec(vec![-3.0, 1.0, -0.5]),
                DVector::from_vec(vec![0.0, -2.0, 0.0]),
            ],
            covariance_trace: cov.trace(),
        }
    }

    fn calibration_with(names: &[&str], cov: &DMatrix<f64>) -> Calibration {
        let mut c = crate::reconstruct::uncertainty::tests::calibration();
        c.covariance = Some(NamedCovariance {
            parameters: names.iter().map(|s| s.to_string()).collect(),
            matrix: cov.clone(),
        });
        c
    }

    #[test]
    fn carry_moves_along_the_quadratic_and_replaces_the_range_term() {
        let names = ["a", "b", "c"];
        let base = DMatrix::from_diagonal(&DVector::from_vec(vec![1.0, 2.0, 3.0]));
        let r = response(&names, &base);
        // The covariance as the calibration wrote it: base plus the range terms.
        let mut cov = base.clone();
        for k in 0..2 {
            cov +=
                (&r.plus[k] * r.plus[k].transpose() + &r.minus[k] * r.minus[k].transpose()) / 6.0;
        }
        let mut r = r;
        r.covariance_trace = cov.trace();
        let cal = calibration_with(&names, &cov);
        // The measurement's numbers: c and a (b moves no point), in another order.
        let mine: Vec<String> = ["c", "a"].iter().map(|s| s.to_string()).collect();
        let sub = DMatrix::from_fn(2, 2, |i, j| cov[([2, 0][i], [2, 0][j])]);
        let (x, sd) = ([15.0, 0.0], [5.0, 5.0]);
        let c = r.carry(&cal, &mine, &sub, x, sd).unwrap();
        // Axis 1: a = (p - m) / 60 = (0.1, 0.0333, 0.01667), b = (p + m) / 1800 = (0, 2/1800, 0).
        assert!((c.shift[1] - 1.5).abs() < 1e-12, "{}", c.shift);
        assert!((c.shift[0] - 0.25).abs() < 1e-12, "{}", c.shift);
        // Covariance: the base's plus g g^T 25 on axis 1 (axis 2 moves neither c nor a).
        let g = DVector::from_vec(vec![1.0 / 60.0, 0.1]);
        let want =
            DMatrix::from_fn(2, 2, |i, j| base[([2, 0][i], [2, 0][j])]) + &g * g.transpose() * 25.0;
        assert!((c.covariance - want).norm() < 1e-12);
        // At an end of the range the move is the change computed there.
        let e = r.carry(&cal, &mine, &sub, [-30.0, 0.0], sd).unwrap();
        assert!((e.shift[1] + 3.0).abs() < 1e-12 && (e.shift[0] + 0.5).abs() < 1e-12);
    }

    #[test]
    fn carry_refuses_outside_the_range_or_another_covariance() {
        let names = ["a", "b", "c"];
        let cov = DMatrix::identity(3, 3);
        let r = response(&names, &cov);
        let cal = calibration_with(&names, &cov);
        let mine: Vec<String> = names.iter().map(|s| s.to_string()).collect();
        let out = r
            .carry(&cal, &mine, &cov, [0.0, -31.0], [5.0, 5.0])
            .unwrap_err();
        assert!(out.contains("outside"), "{out}");
        let other = calibration_with(&names, &(cov.clone() * 2.0));
        let err = r
            .carry(&other, &mine, &cov, [0.0, 0.0], [5.0, 5.0])
            .unwrap_err();
        assert!(err.contains("not the one"), "{err}");
        assert!(r
            .carry(&cal, &[], &DMatrix::zeros(0, 0), [0.0; 2], [5.0; 2])
            .is_err());
    }

    #[test]
    fn offsets_project_and_floor() {
        let cov = DMatrix::identity(3, 3);
        let r = response(&["a", "b", "c"], &cov);
        let e = Vector3::new(2.0, -7.0, 100.0);
        // The sphere's basis turned 90 degrees: its first axis is our second.
        let (x, sd) = r.offsets(&EmitterSample {
            emitter_cam_mm: e,
            sd_mm: [8.0, 0.1],
            basis: [Vector3::y(), -Vector3::x()],
        });
        assert_eq!(x, [2.0, -7.0]);
        assert_eq!(sd, [EMITTER_SD_FLOOR_MM, 8.0]);
    }

    #[test]
    fn json_round_trips_and_malformed_is_named() {
        let cov = DMatrix::identity(3, 3);
        let r = response(&["a", "b", "c"], &cov);
        let mut cal = calibration_with(&["a", "b", "c"], &cov);
        assert_eq!(EmitterResponse::of(&cal).unwrap(), None);
        cal.extra.insert(
            "board_stripe_bias".into(),
            json!({"emitter_response": r.to_json()}),
        );
        assert_eq!(EmitterResponse::of(&cal).unwrap(), Some(r.clone()));
        let mut bad = r.to_json();
        bad["plus"] = json!([[1.0, 2.0], [1.0, 2.0, 3.0]]);
        cal.extra
            .insert("board_stripe_bias".into(), json!({"emitter_response": bad}));
        let e = EmitterResponse::of(&cal).unwrap_err().to_string();
        assert!(e.contains("emitter_response") && e.contains("plus"), "{e}");
    }
}
