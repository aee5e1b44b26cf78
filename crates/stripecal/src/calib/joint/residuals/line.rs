//! The stripe's line in a view (where the laser plane meets the board plane) and the foot
//! point of an image point on that line's image.

use nalgebra::Vector3;

use crate::error::{Error, Result};
use crate::model::camera::{project_generic, Camera};
use crate::numerics::dual::{Dual, Scalar};
use crate::numerics::mat3::{cross, dot};

pub(super) fn parallel_error(view: usize) -> Error {
    Error::Degenerate(format!(
        "the laser plane is parallel to the board plane of view {view} (of the views used)"
    ))
}

/// The line where the laser plane `(n1, d1)` meets the board plane (third column of
/// `rot`, through `t`): a point and a unit direction, camera frame.
pub(super) fn stripe_line<T: Scalar>(
    n1: &[T; 3],
    d1: T,
    rot: &[[T; 3]; 3],
    t: &[T; 3],
) -> Result<([T; 3], [T; 3])> {
    let n2 = [rot[0][2], rot[1][2], rot[2][2]];
    let d2 = dot(&n2, t);
    let dir = cross(n1, &n2);
    let s2 = dot(&dir, &dir);
    if s2.value().is_nan() || s2.value() <= 1e-18 {
        return Err(Error::Degenerate(
            "the laser plane is parallel to a view's board plane".into(),
        ));
    }
    let a = cross(&n2, &dir);
    let b = cross(&dir, n1);
    let p: [T; 3] = std::array::from_fn(|i| (a[i] * d1 + b[i] * d2) / s2);
    let s = s2.sqrt();
    let u: [T; 3] = std::array::from_fn(|i| dir[i] / s);
    Ok((p, u))
}

/// Foot point of `target` on the image of the 3D line `p0 + s dir`: `s*`, and the unit
/// normal of the image curve there. Gauss-Newton along the line from the distortion-free
/// closest point; brown5 inlined (duals), another model through its trait.
pub(super) fn foot_point(
    cam: &Camera,
    p0: &[f64; 3],
    dir: &[f64; 3],
    target: [f64; 2],
    start: f64,
) -> Result<(f64, [f64; 2])> {
    // Start: closest point of the 3D line to the distortion-free viewing ray.
    let r = Vector3::new(
        (target[0] - cam.u0) / cam.fu,
        (target[1] - cam.v0) / cam.fv,
        1.0,
    )
    .normalize();
    let (pv, dv) = (Vector3::from(*p0), Vector3::from(*dir));
    let b = dv.dot(&r);
    let den = 1.0 - b * b;
    let mut s = if start.is_finite() {
        start
    } else if den > 1e-12 {
        (b * r.dot(&pv) - dv.dot(&pv)) / den
    } else {
        0.0
    };
    let params = cam.params();
    let cd: [Dual<1>; 9] = std::array::from_fn(|i| Dual::cst(params[i]));
    let brown5 = cam.projection.is_brown5();
    let mut normal = [0.0, 0.0];
    for it in 0..30 {
        let sd = Dual::<1>::var(s, 0);
        let p: [Dual<1>; 3] = std::array::from_fn(|i| Dual::cst(p0[i]) + sd.scale(dir[i]));
        if p[2].v <= 0.0 {
            return Err(Error::Degenerate(
                "a view's stripe line passes behind the camera".into(),
            ));
        }
        let (uv, j) = if brown5 {
            let uv = project_generic(&cd, &p);
            ([uv[0].v, uv[1].v], [uv[0].d[0], uv[1].d[0]])
        } else {
            let pv = Vector3::new(p[0].v, p[1].v, p[2].v);
            let (uv, jp, _) = cam.project_with_jacobians(&pv)?;
            let j = jp * Vector3::from(*dir);
            ([uv.x, uv.y], [j.x, j.y])
        };
        let res = [uv[0] - target[0], uv[1] - target[1]];
        let jj = j[0] * j[0] + j[1] * j[1];
        if jj.is_nan() || jj <= 1e-300 || !jj.is_finite() {
            return Err(Error::Degenerate(
                "a view's stripe line images as a point".into(),
            ));
        }
        let jn = jj.sqrt();
        normal = [-j[1] / jn, j[0] / jn];
        let step = -(j[0] * res[0] + j[1] * res[1]) / jj;
        s += step;
        if (step * jn).abs() < 1e-11 || it == 29 {
            break;
        }
    }
    Ok((s, normal))
}
