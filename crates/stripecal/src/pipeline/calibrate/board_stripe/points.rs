//! The stripe points with a width as the model sees them: each point on its view's
//! board plane (camera frame), its scan-line coordinates, width and saturation.

use nalgebra::Vector3;

use super::Pt;
use crate::calib::laser_plane::backproject_to_board;
use crate::calib::ViewObs;
use crate::model::camera::Camera;
use crate::model::geometry::{Iso3, Plane};
use crate::stripe_model::{BoardSurface, Rig};

/// The views' board planes in the camera frame.
pub(super) fn board_planes(cam_board: &[Iso3]) -> Vec<Plane> {
    cam_board
        .iter()
        .map(|cb| {
            let n = cb.rotation * Vector3::z();
            Plane {
                normal: n,
                d: n.dot(&cb.translation.vector),
            }
        })
        .collect()
}

/// The boards as the model sees them for a rig (`None`: the sheet parallel to one).
pub(super) fn surfaces<'b>(rig: &Rig<'_>, boards: &'b [Plane]) -> Vec<Option<BoardSurface<'b>>> {
    boards.iter().map(|b| BoardSurface::new(rig, b)).collect()
}

/// Every stripe point of a view with widths and saturation flags, back-projected onto
/// its board (`along`: the coordinate along the scan line).
pub(super) fn stripe_points(
    views: &[ViewObs],
    cam_board: &[Iso3],
    camera: &Camera,
    along: usize,
) -> Vec<Pt> {
    let mut pts = Vec::new();
    for (vi, (v, cb)) in views.iter().zip(cam_board).enumerate() {
        let Some(shape) = v.stripe_shape.as_ref() else {
            continue;
        };
        if shape.width_px.len() != v.stripe.len() || shape.saturated.len() != v.stripe.len() {
            continue;
        }
        let each = v.stripe.iter().zip(&shape.width_px).zip(&shape.saturated);
        for (k, ((uv, w), sat)) in each.enumerate() {
            let Ok(p) = backproject_to_board(camera, cb, uv) else {
                continue;
            };
            pts.push(Pt {
                view: vi,
                idx: k,
                p,
                line: uv[1 - along],
                a: uv[along],
                width: *w,
                saturated: *sat,
            });
        }
    }
    pts
}
