//! Per-image truth for the vision tests.
//!
//! - Target points ([`PointTruth`], one per point of the board that is imaged):
//!   - circles (`circles`, `asymmetric_circles`): the centre of each imaged circle is
//!     the area centroid of its exactly projected outline (the circle's boundary sampled
//!     densely in board coordinates, transformed, distorted and projected; shoelace
//!     centroid). This is NOT the projection of the circle's centre: perspective shifts
//!     it. A circle counts as imaged when its whole outline is inside the image.
//!   - chessboard corners: the exact projection (pinhole and distortion) of the corner
//!     point; a corner is a point, so it has no perspective bias, and `(u, v)` equals
//!     `(u_center_proj, v_center_proj)`. A corner counts as imaged when that point is
//!     inside the image.
//! - Stripe: the projection of the laser plane's intersection with the surfaces (plate,
//!   table, sphere), one point per scan line where the curve crosses it, kept only where
//!   the camera sees that surface point and the laser lights it. Each point carries the
//!   facts a test needs to leave out places where a real stripe is biased too: the
//!   incidence and viewing angles, the distance to the nearest reflectance edge and the
//!   slope of the curve against the scan line.

use nalgebra::{Vector2, Vector3};
use serde::Serialize;

use stripecal::model::StripeDirection;
use stripecal::Camera;

use crate::scene::{ImageScene, SURF_FREE_PLATE, SURF_PLATE, SURF_SPHERE, SURF_TABLE};

/// Vertices of the polygon approximating a projected circle outline.
const OUTLINE_VERTICES: usize = 4096;

/// Truth of one imaged target point: a circle's centre or a chessboard's inner corner.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PointTruth {
    pub row: usize,
    pub col: usize,
    /// The point's true image position, px: a circle's area centroid of the projected
    /// outline; a chessboard corner's projection (== `u_center_proj, v_center_proj`).
    pub u: f64,
    pub v: f64,
    /// Projection of the point ([`stripecal::Board::center`]): for circles, for
    /// comparison (it differs from (u, v) by the perspective bias).
    pub u_center_proj: f64,
    pub v_center_proj: f64,
}

/// The former name of [`PointTruth`] (circle grids).
pub type CircleTruth = PointTruth;

/// Truth of one stripe point.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StripePointTruth {
    pub u: f64,
    pub v: f64,
    /// `board`, `table`, `sphere` or `flat_plate` (the free plate).
    pub surface: &'static str,
    /// The 3D point in the camera frame, mm.
    pub p_cam: [f64; 3],
    /// Angle between the surface normal and the direction to the emitter, deg.
    pub incidence_deg: f64,
    /// Angle between the surface normal and the direction to the camera, deg.
    pub view_deg: f64,
    /// Distance on the surface to the nearest reflectance edge (circle border, square
    /// side, plate edge), mm; 99 where there is none nearby.
    pub edge_mm: f64,
    /// d(other coordinate) / d(scan-line coordinate) of the projected curve.
    pub slope: f64,
}

/// The imaged target points of a scene, row-major: circles entirely inside the image
/// (with `margin_px`) and in front of the camera; chessboard corners inside the image
/// (with `margin_px`) and in front of the camera. See the module docs.
pub fn target_truth(scene: &ImageScene, cam: &Camera, margin_px: f64) -> Vec<PointTruth> {
    let board = scene.board();
    let t = scene.cam_board;
    let mut out = Vec::new();
    for (r, c) in board.indices() {
        let ctr = board.center(r, c);
        let rad = 0.5 * board.diameter(r, c);
        if rad == 0.0 {
            // a chessboard corner: a point
            if let Ok(uv) = cam.project(&(t * scene.sheet_point(ctr.x, ctr.y)).coords) {
                if cam.contains(&uv, margin_px) {
                    out.push(PointTruth {
                        row: r,
                        col: c,
                        u: uv.x,
                        v: uv.y,
                        u_center_proj: uv.x,
                        v_center_proj: uv.y,
                    });
                }
            }
            continue;
        }
        let mut pts = Vec::with_capacity(OUTLINE_VERTICES);
        let mut ok = true;
        for k in 0..OUTLINE_VERTICES {
            let a = std::f64::consts::TAU * k as f64 / OUTLINE_VERTICES as f64;
            let pb = scene.sheet_point(ctr.x + rad * a.cos(), ctr.y + rad * a.sin());
            match cam.project(&(t * pb).coords) {
                Ok(uv) if cam.contains(&uv, margin_px) => pts.push(uv),
                _ => {
                    ok = false;
                    break;
                }
            }
        }
        if !ok {
            continue;
        }
        let (cu, cv) = polygon_centroid(&pts);
        let Ok(cp) = cam.project(&(t * scene.sheet_point(ctr.x, ctr.y)).coords) else {
            continue;
        };
        out.push(PointTruth {
            row: r,
            col: c,
            u: cu,
            v: cv,
            u_center_proj: cp.x,
            v_center_proj: cp.y,
        });
    }
    out
}

/// [`target_truth`] under its former name (circle grids).
pub fn circle_truth(scene: &ImageScene, cam: &Camera, margin_px: f64) -> Vec<PointTruth> {
    target_truth(scene, cam, margin_px)
}

/// Area centroid of a closed polygon (shoelace). Vertices are taken relative to the
/// first one to keep round-off small.
pub fn polygon_centroid(pts: &[Vector2<f64>]) -> (f64, f64) {
    let o = pts[0];
    let (mut a, mut cx, mut cy) = (0.0, 0.0, 0.0);
    for i in 0..pts.len() {
        let p = pts[i] - o;
        let q = pts[(i + 1) % pts.len()] - o;
        let cross = p.x * q.y - q.x * p.y;
        a += cross;
        cx += (p.x + q.x) * cross;
        cy += (p.y + q.y) * cross;
    }
    (o.x + cx / (3.0 * a), o.y + cy / (3.0 * a))
}

/// The direction a stripe runs in an image: from the projected direction of the laser
/// plane's intersection with a fronto-parallel plane at `depth_mm`.
pub fn stripe_direction(scene: &ImageScene, cam: &Camera, depth_mm: f64) -> StripeDirection {
    let n = scene.laser.plane.normal;
    let d = scene.laser.plane.d;
    // Line: n . p = d, z = depth. Direction = n x z.
    let dir = n.cross(&Vector3::z());
    let base = if n.x.abs() > n.y.abs() {
        Vector3::new((d - n.z * depth_mm) / n.x, 0.0, depth_mm)
    } else {
        Vector3::new(0.0, (d - n.z * depth_mm) / n.y, depth_mm)
    };
    let (Ok(a), Ok(b)) = (cam.project(&base), cam.project(&(base + dir * 5.0))) else {
        return StripeDirection::Cols;
    };
    let dd = b - a;
    if dd.y.abs() >= dd.x.abs() {
        StripeDirection::Cols
    } else {
        StripeDirection::Rows
    }
}

/// The true stripe centre line of one image, one point per scan line crossing.
/// `direction` must be `Rows` (one point per column) or `Cols` (one per row).
pub fn stripe_truth(
    scene: &ImageScene,
    cam: &Camera,
    direction: StripeDirection,
) -> Vec<StripePointTruth> {
    let mut out = Vec::new();
    let laser = scene.laser.plane;
    let per_row = direction != StripeDirection::Rows;
    let tr = Tracing {
        scene,
        cam,
        per_row,
    };
    // Plate, table and the free plate: lines.
    let mut planes = Vec::with_capacity(3);
    if scene.has_table() {
        planes.push((SURF_PLATE, scene.plate_plane()));
        planes.push((SURF_TABLE, scene.table_plane()));
    }
    if let Some(pl) = scene.free_plate_plane() {
        planes.push((SURF_FREE_PLATE, pl));
    }
    for (surface, (pn, pd)) in planes {
        let dir = laser.normal.cross(&pn);
        if dir.norm() < 1e-9 {
            continue;
        }
        let dir = dir.normalize();
        // A point on both planes: minimise |p| subject to the two plane equations.
        let n1 = laser.normal;
        let (d1, d2) = (laser.d, pd);
        let n1n2 = n1.dot(&pn);
        let det = 1.0 - n1n2 * n1n2;
        let c1 = (d1 - d2 * n1n2) / det;
        let c2 = (d2 - d1 * n1n2) / det;
        let p0 = n1 * c1 + pn * c2;
        let curve = |t: f64| p0 + dir * t;
        let c = StripeCurve {
            surface,
            curve: &curve,
        };
        trace(tr, c, -1000.0, 1000.0, 200_000, &mut out);
    }
    for &(c, r) in scene.spheres() {
        let dist = laser.signed_distance(&c);
        if dist.abs() < r {
            let center = c - laser.normal * dist;
            let rho = (r * r - dist * dist).sqrt();
            let e1 = laser.normal.cross(&Vector3::z()).normalize();
            let e2 = laser.normal.cross(&e1);
            let curve = |t: f64| center + (e1 * t.cos() + e2 * t.sin()) * rho;
            let c = StripeCurve {
                surface: SURF_SPHERE,
                curve: &curve,
            };
            trace(tr, c, 0.0, std::f64::consts::TAU, 20_000, &mut out);
        }
    }
    out.sort_by(|a, b| {
        let (ka, kb) = if per_row { (a.v, b.v) } else { (a.u, b.u) };
        ka.total_cmp(&kb)
    });
    out
}

/// What stripes are traced in: the scene, its camera and whether a point is found per
/// image row (`true`) or per column.
#[derive(Clone, Copy)]
struct Tracing<'a> {
    scene: &'a ImageScene,
    cam: &'a Camera,
    per_row: bool,
}

/// One surface's stripe: the surface and the stripe's points (camera frame) by a
/// curve parameter.
#[derive(Clone, Copy)]
struct StripeCurve<'c> {
    surface: u32,
    curve: &'c dyn Fn(f64) -> Vector3<f64>,
}

/// Pushes onto `out` the stripe points of `c` where it crosses a scan line, the curve
/// sampled at `samples` steps over `[t0, t1]`.
fn trace(
    tr: Tracing,
    c: StripeCurve,
    t0: f64,
    t1: f64,
    samples: usize,
    out: &mut Vec<StripePointTruth>,
) {
    let Tracing { cam, per_row, .. } = tr;
    let curve = c.curve;
    let scan = |t: f64| -> Option<f64> {
        let p = curve(t);
        if p.z <= 1e-6 {
            return None;
        }
        let uv = cam.project(&p).ok()?;
        if !cam.contains(&uv, 0.0) {
            return None;
        }
        Some(if per_row { uv.y } else { uv.x })
    };
    let n_lines = if per_row { cam.height } else { cam.width } as f64;
    let mut prev: Option<(f64, f64)> = None;
    for k in 0..=samples {
        let t = t0 + (t1 - t0) * k as f64 / samples as f64;
        let cur = scan(t).map(|s| (t, s));
        if let (Some((ta, sa)), Some((tb, sb))) = (prev, cur) {
            // integer scan lines in the half-open interval (min, max]
            let (lo, hi) = if sa < sb { (sa, sb) } else { (sb, sa) };
            let mut line = lo.floor() + 1.0;
            while line <= hi {
                if line >= 0.0 && line < n_lines {
                    if let Some(pt) = refine(tr, c, &scan, ta, tb, sa, line) {
                        out.push(pt);
                    }
                }
                line += 1.0;
            }
        }
        prev = cur;
    }
}

/// The point of `c` on scan line `line`, bisected between the curve parameters `ta`
/// and `tb` (`sa`: the scan coordinate at `ta`), when the camera sees it lit.
fn refine(
    tr: Tracing,
    c: StripeCurve,
    scan: &dyn Fn(f64) -> Option<f64>,
    ta: f64,
    tb: f64,
    sa: f64,
    line: f64,
) -> Option<StripePointTruth> {
    let Tracing {
        scene,
        cam,
        per_row,
    } = tr;
    let StripeCurve { surface, curve } = c;
    let (mut a, mut b) = (ta, tb);
    let mut fa = sa - line;
    for _ in 0..80 {
        let m = 0.5 * (a + b);
        let fm = scan(m)? - line;
        if (fm < 0.0) == (fa < 0.0) {
            a = m;
            fa = fm;
        } else {
            b = m;
        }
    }
    let t = 0.5 * (a + b);
    let p = curve(t);
    let uv = cam.project(&p).ok()?;
    // Visibility: the camera ray through p must hit this surface first, at p.
    let dir = p / p.z;
    let (surf, s) = scene.first_hit(&dir)?;
    if surf != surface || (s - p.z).abs() > 1e-6 * p.z {
        return None;
    }
    if !scene.lit(surface, &p) {
        return None;
    }
    let nrm = scene.normal_at(surface, &p);
    let to_e = (scene.laser.emitter - p).normalize();
    let incidence_deg = nrm.dot(&to_e).clamp(-1.0, 1.0).acos().to_degrees();
    let view_deg = nrm
        .dot(&(-p).normalize())
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees();
    let edge_mm = match surface {
        SURF_PLATE => {
            let (x, y) = scene.board_xy(&p);
            scene.plate_edge_distance(x, y).min(99.0)
        }
        SURF_TABLE => {
            // Distance to the plate outline (the plate's edge casts the nearest step).
            let (x, y) = scene.board_xy(&p);
            let e = scene.plate_extent();
            let dx = (e[0] - x).max(x - e[1]).max(0.0);
            let dy = (e[2] - y).max(y - e[3]).max(0.0);
            (dx * dx + dy * dy).sqrt().min(99.0)
        }
        SURF_FREE_PLATE => scene.free_plate_inside(&p).unwrap_or(0.0).min(99.0),
        _ => 99.0,
    };
    // slope of the curve in the image
    let h = (tb - ta).abs() * 1e-3 + 1e-9;
    let slope = match (cam.project(&curve(t - h)), cam.project(&curve(t + h))) {
        (Ok(p1), Ok(p2)) => {
            let d = p2 - p1;
            if per_row {
                d.x / d.y
            } else {
                d.y / d.x
            }
        }
        _ => f64::NAN,
    };
    Some(StripePointTruth {
        u: uv.x,
        v: uv.y,
        surface: match surface {
            SURF_PLATE => "board",
            SURF_TABLE => "table",
            SURF_FREE_PLATE => "flat_plate",
            _ => "sphere",
        },
        p_cam: [p.x, p.y, p.z],
        incidence_deg,
        view_deg,
        edge_mm,
        slope,
    })
}
