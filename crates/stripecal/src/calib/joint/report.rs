//! The adjustment's figures after the solve: unweighted residuals, per-view RMS (px and
//! mm on the board), outlier flags, and the overall RMS values.

use nalgebra::Vector3;

use super::layout::JointParams;
use super::residuals::JointProblem;
use super::ViewReport;

/// The per-residual and per-view figures of a solution.
pub(super) struct Reports {
    pub views: Vec<ViewReport>,
    pub circle_residuals: Vec<(usize, usize, usize, f64, f64, f64, f64)>,
    pub stripe_residuals: Vec<(usize, f64, f64, f64)>,
    pub circle_rms_px: f64,
    pub stripe_rms_px: f64,
    pub stripe_rms_mm: f64,
    /// The final sigmas (circle, stripe), px.
    pub sigma_px: (f64, f64),
}

/// Sums of squares and counts of one view.
#[derive(Debug, Clone, Copy, Default)]
struct ViewSums {
    circle_ss: f64,
    circles: usize,
    stripe_ss: f64,
    stripes: usize,
    stripe_ss_mm: f64,
}

/// The figures of the solution `s` whose weighted residuals are `weighted`; outlier
/// views (RMS beyond `outlier_sigmas`) get a warning.
pub(super) fn build(
    problem: &JointProblem<'_>,
    s: &JointParams,
    weighted: &[f64],
    outlier_sigmas: f64,
    warnings: &mut Vec<String>,
) -> Reports {
    let terms = &problem.terms;
    let m_c = 2 * terms.circles.len();
    let m_s = terms.stripes.len();
    // The solver's final residuals carry the last round's weights.
    let (sc_final, ss_final) = (1.0 / problem.wc(), 1.0 / problem.ws());
    let raw: Vec<f64> = weighted
        .iter()
        .enumerate()
        .map(|(i, r)| r * if i < m_c { sc_final } else { ss_final })
        .collect();
    let mut sums = vec![ViewSums::default(); terms.a.len()];
    let mut circle_residuals = Vec::with_capacity(terms.circles.len());
    for (k, c) in terms.circles.iter().enumerate() {
        let (du, dv) = (raw[2 * k], raw[2 * k + 1]);
        circle_residuals.push((terms.used[c.view], c.row, c.col, c.u, c.v, du, dv));
        sums[c.view].circle_ss += du * du + dv * dv;
        sums[c.view].circles += 1;
    }
    let mm_per_px = mm_per_px(problem, s);
    let mut stripe_residuals = Vec::with_capacity(m_s);
    for (k, st) in terms.stripes.iter().enumerate() {
        let d = raw[m_c + k];
        stripe_residuals.push((terms.used[st.view], st.u, st.v, d));
        let e = &mut sums[st.view];
        e.stripe_ss += d * d;
        e.stripes += 1;
        e.stripe_ss_mm += (d * mm_per_px[st.view]).powi(2);
    }
    let mut views = Vec::new();
    let mut ss_mm = 0.0;
    for (vi, &view) in terms.used.iter().enumerate() {
        ss_mm += sums[vi].stripe_ss_mm;
        let r = view_report(
            view,
            &sums[vi],
            (sc_final, ss_final),
            outlier_sigmas,
            warnings,
        );
        views.push(r);
    }
    let circle_ss: f64 = raw[..m_c].iter().map(|x| x * x).sum();
    let stripe_ss: f64 = raw[m_c..].iter().map(|x| x * x).sum();
    Reports {
        views,
        circle_residuals,
        stripe_residuals,
        circle_rms_px: if m_c > 0 {
            (circle_ss / (m_c / 2) as f64).sqrt()
        } else {
            f64::NAN
        },
        stripe_rms_px: (stripe_ss / m_s as f64).sqrt(),
        stripe_rms_mm: (ss_mm / m_s as f64).sqrt(),
        sigma_px: (sc_final, ss_final),
    }
}

/// mm per px on the board for each view's stripe: the image length of 1 mm of the
/// stripe line's normal offset, estimated from the view's pose.
fn mm_per_px(problem: &JointProblem<'_>, s: &JointParams) -> Vec<f64> {
    s.view_poses(&problem.flanges(s))
        .into_iter()
        .map(|(rot, t)| {
            let depth = Vector3::from(t).norm();
            let tilt = rot[2][2].abs().max(0.1);
            // Image scale of the board at the stand-off, corrected for its tilt.
            depth / (0.5 * (s.cam[0] + s.cam[1])) / tilt
        })
        .collect()
}

/// The report of one view (dataset row `view`) from its sums, with the final sigmas
/// `(circle, stripe)` for the outlier test.
fn view_report(
    view: usize,
    v: &ViewSums,
    (sc_final, ss_final): (f64, f64),
    outlier_sigmas: f64,
    warnings: &mut Vec<String>,
) -> ViewReport {
    let crms = if v.circles > 0 {
        (v.circle_ss / v.circles as f64).sqrt()
    } else {
        f64::NAN
    };
    let srms = if v.stripes > 0 {
        (v.stripe_ss / v.stripes as f64).sqrt()
    } else {
        f64::NAN
    };
    let smm = if v.stripes > 0 {
        (v.stripe_ss_mm / v.stripes as f64).sqrt()
    } else {
        f64::NAN
    };
    // RMS per coordinate in sigmas.
    let zc = crms / std::f64::consts::SQRT_2 / sc_final;
    let zs = srms / ss_final;
    let outlier = zc > outlier_sigmas || zs > outlier_sigmas;
    if outlier {
        warnings.push(format!(
            "view {view}: outlier (circle RMS {crms:.4} px, stripe RMS {srms:.4} px vs \
             sigmas {sc_final:.4} / {ss_final:.4} px per coordinate)"
        ));
    }
    ViewReport {
        view,
        circles: v.circles,
        stripe_points: v.stripes,
        circle_rms_px: crms,
        stripe_rms_px: srms,
        stripe_rms_mm: smm,
        outlier,
    }
}
