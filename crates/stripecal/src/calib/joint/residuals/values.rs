//! The image residuals' values in f64 (unweighted): circle centres (detected minus
//! predicted) and stripe points' signed distances to the imaged stripe line.

use std::sync::atomic::Ordering;

use rayon::prelude::*;

use super::line::{foot_point, parallel_error, stripe_line};
use super::JointProblem;
use nalgebra::Vector3;

use crate::calib::conic::{centre_any_model, centre_generic_n, quadrature_nodes};
use crate::error::Result;
use crate::model::camera::{project_generic, Camera};

impl JointProblem<'_> {
    /// Stripe foot point from the warm-start cache, which it updates.
    pub(super) fn cached_foot_point(
        &self,
        k: usize,
        cam: &Camera,
        p0: &[f64; 3],
        dir: &[f64; 3],
    ) -> Result<(f64, [f64; 2])> {
        let (st, cache) = (&self.terms.stripes[k], &self.foot_cache[k]);
        let start = f64::from_bits(cache.load(Ordering::Relaxed));
        let (sf, normal) = foot_point(cam, p0, dir, [st.u, st.v], start)?;
        cache.store(sf.to_bits(), Ordering::Relaxed);
        Ok((sf, normal))
    }

    /// f64 residuals (unweighted): circles (2 each) then stripe points.
    pub(super) fn raw_residuals(&self, p: &[f64], r: &mut [f64]) -> Result<()> {
        let s = self.decode(p);
        let cam = self.base.with_params(&s.cam);
        let brown5 = cam.projection.is_brown5();
        let a = self.flanges(&s);
        let poses = s.view_poses(&a);
        let board_poses = s.circle_poses(&a);
        let n1 = [s.plane_n.x, s.plane_n.y, s.plane_n.z];
        let lines: Vec<Option<_>> = poses
            .iter()
            .map(|(rot, t)| stripe_line(&n1, s.plane_d, rot, t).ok())
            .collect();
        let nc = self.terms.circles.len();
        let (rc, rs) = r.split_at_mut(2 * nc);
        rc.par_chunks_mut(2)
            .zip(self.terms.circles.par_iter())
            .try_for_each(|(out, c)| -> Result<()> {
                let (rot, t) = &board_poses[c.view];
                let uv = if brown5 {
                    centre_generic_n(
                        &s.cam,
                        rot,
                        t,
                        c.centre,
                        c.radius,
                        self.model,
                        quadrature_nodes(self.base.model),
                    )?
                } else {
                    centre_any_model(&cam, rot, t, c.centre, c.radius, self.model)?
                };
                out[0] = uv[0] - c.u;
                out[1] = uv[1] - c.v;
                Ok(())
            })?;
        rs.par_iter_mut()
            .enumerate()
            .try_for_each(|(k, out)| -> Result<()> {
                let st = &self.terms.stripes[k];
                let Some((p0, dir)) = lines[st.view] else {
                    return Err(parallel_error(st.view));
                };
                let (sf, normal) = self.cached_foot_point(k, &cam, &p0, &dir)?;
                let pt: [f64; 3] = std::array::from_fn(|i| p0[i] + sf * dir[i]);
                let uv = if brown5 {
                    project_generic(&s.cam, &pt)
                } else {
                    let uv = cam.project(&Vector3::from(pt))?;
                    [uv.x, uv.y]
                };
                *out = normal[0] * (uv[0] - st.u) + normal[1] * (uv[1] - st.v);
                Ok(())
            })?;
        Ok(())
    }
}
