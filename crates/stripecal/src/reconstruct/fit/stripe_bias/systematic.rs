//! The systematic parts a sphere's stripe-bias correction leaves, each a SIGNED effect on
//! the diameter and the centre of one source, and what the source is shared with.
//!
//! A ball bar's length is the difference of two corrected centres, so what matters is
//! which of the parts its two spheres share:
//! - the model's neglected terms ([`SystematicKind::Model`]): the same relative error
//!   for every sphere the model corrects, signed as each correction (it largely cancels
//!   in a ball bar's length, two spheres being corrected alike);
//! - the emitter when it is assumed, not estimated ([`SystematicKind::AssumedEmitter`],
//!   one per in-plane axis): one physical emitter for every scan of the sensor, so two
//!   spheres' centres move together when it is elsewhere;
//! - what the scan estimates from its own stripe ([`SystematicKind::Estimate`]: the
//!   emitter's two in-plane coordinates from the brightness, the sheet's and the PSF's
//!   sigmas from the widths): each sphere's estimate errs on its own, so two spheres'
//!   parts are independent and add in a ball bar's length.
//!
//! Each part is read as the change of the corrected fit (module docs of
//! [`super`]): half the change between `+-1` standard uncertainty of an estimate; for the
//! assumed emitter, the larger change at the two ends of `+-emitter_range_mm` (the half
//! width of a uniform distribution, `/ sqrt 3`) with the sign of the change from one end
//! to the other; for the neglected terms, [`super::neglected_share`] of the correction.

use nalgebra::Vector3;

/// What a systematic part is shared with (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SystematicKind {
    /// The model's neglected terms: shared by every sphere the model corrects.
    Model,
    /// The assumed emitter's position along in-plane axis `k` (0 or 1): shared by every
    /// scan of the sensor.
    AssumedEmitter(u32),
    /// This scan's own estimate `k`: 0, 1 the emitter's in-plane coordinates, 2 the
    /// sheet's sigma, 3 the PSF's sigma. Independent between scans.
    Estimate(u32),
}

/// One systematic part: the signed standard uncertainty of the diameter and of each
/// centre coordinate, mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SystematicPart {
    pub kind: SystematicKind,
    pub diameter_mm: f64,
    pub center_mm: Vector3<f64>,
}

/// A change of the corrected fit: `(diameter, centre)`, mm.
pub(super) type Change = (f64, Vector3<f64>);

/// Half the difference of the fits at `+-u` of an estimate: a signed standard part.
pub(super) fn estimate_part(
    k: u32,
    plus: Option<Change>,
    minus: Option<Change>,
) -> Option<SystematicPart> {
    let (a, b) = (plus?, minus?);
    Some(SystematicPart {
        kind: SystematicKind::Estimate(k),
        diameter_mm: 0.5 * (a.0 - b.0),
        center_mm: 0.5 * (a.1 - b.1),
    })
}

/// The assumed emitter's part along axis `k` from the fits' changes at the two ends of
/// its range: per quantity the larger magnitude over `sqrt 3`, signed as the change from
/// the minus end to the plus end (the magnitude alone where the two ends agree in sign).
pub(super) fn assumed_emitter_part(
    k: u32,
    plus: Option<Change>,
    minus: Option<Change>,
) -> Option<SystematicPart> {
    let (a, b) = match (plus, minus) {
        (None, None) => return None,
        (a, b) => (
            a.unwrap_or((0.0, Vector3::zeros())),
            b.unwrap_or((0.0, Vector3::zeros())),
        ),
    };
    let one = |x: f64, y: f64| {
        let m = x.abs().max(y.abs()) / 3f64.sqrt();
        if x - y < 0.0 {
            -m
        } else {
            m
        }
    };
    Some(SystematicPart {
        kind: SystematicKind::AssumedEmitter(k),
        diameter_mm: one(a.0, b.0),
        center_mm: Vector3::from_fn(|i, _| one(a.1[i], b.1[i])),
    })
}

/// The neglected terms' part: `share` of the correction, signed as it.
pub(super) fn model_part(
    share: f64,
    diameter_change: f64,
    center_change: &Vector3<f64>,
) -> SystematicPart {
    SystematicPart {
        kind: SystematicKind::Model,
        diameter_mm: share * diameter_change,
        center_mm: center_change * share,
    }
}

/// The root sum of squares of the parts of a quantity (`q(part)`), optionally only those
/// `which` selects.
pub(super) fn rss(
    parts: &[SystematicPart],
    which: impl Fn(&SystematicKind) -> bool,
    q: impl Fn(&SystematicPart) -> f64,
) -> f64 {
    parts
        .iter()
        .filter(|p| which(&p.kind))
        .map(|p| q(p).powi(2))
        .sum::<f64>()
        .sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ch(d: f64, c: [f64; 3]) -> Option<Change> {
        Some((d, Vector3::from(c)))
    }

    #[test]
    fn estimate_part_is_half_the_signed_difference() {
        let p = estimate_part(2, ch(0.003, [1.0, -2.0, 0.0]), ch(0.001, [-1.0, 2.0, 0.5])).unwrap();
        assert_eq!(p.kind, SystematicKind::Estimate(2));
        assert!((p.diameter_mm - 0.001).abs() < 1e-15);
        assert_eq!(p.center_mm, Vector3::new(1.0, -2.0, -0.25));
        assert!(estimate_part(0, None, ch(0.0, [0.0; 3])).is_none());
    }

    #[test]
    fn assumed_emitter_part_takes_the_larger_end_with_the_slope_sign() {
        let s3 = 3f64.sqrt();
        // Plus end -0.2, minus end +0.6: decreasing, magnitude 0.6.
        let p =
            assumed_emitter_part(1, ch(-0.2, [0.3, 0.0, 0.0]), ch(0.6, [-0.1, 0.0, 0.0])).unwrap();
        assert_eq!(p.kind, SystematicKind::AssumedEmitter(1));
        assert!((p.diameter_mm + 0.6 / s3).abs() < 1e-15);
        assert!((p.center_mm.x - 0.3 / s3).abs() < 1e-15);
        // One end failing: the other alone.
        let q = assumed_emitter_part(0, None, ch(0.6, [0.0; 3])).unwrap();
        assert!((q.diameter_mm + 0.6 / s3).abs() < 1e-15);
        assert!(assumed_emitter_part(0, None, None).is_none());
    }

    #[test]
    fn rss_selects_and_combines() {
        let parts = [
            model_part(0.1, 0.004, &Vector3::new(0.0, 0.0, -0.002)),
            estimate_part(0, ch(0.0003, [0.0; 3]), ch(0.0, [0.0; 3])).unwrap(),
        ];
        let all = rss(&parts, |_| true, |p| p.diameter_mm);
        assert!((all - (0.0004f64.powi(2) + 0.00015f64.powi(2)).sqrt()).abs() < 1e-15);
        let shared = rss(&parts, |k| *k == SystematicKind::Model, |p| p.center_mm.z);
        assert!((shared - 0.0002).abs() < 1e-15);
    }
}
