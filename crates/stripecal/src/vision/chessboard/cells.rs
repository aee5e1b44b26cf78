//! Square colours: the intensity of a lattice cell (median of samples over its
//! central part, so a thin bright stripe or a printed line does not change it),
//! the check of a link between neighbouring corners, and the colour phase of a grid.

use super::image::Gray;
use super::lattice::{cell_dark, Coord, CoordMap};

/// Median of `n x n` bilinear samples of `g` at `c + s e1 + t e2`, `s, t` spread
/// evenly over `[-half, half]`; `None` when fewer than 3/4 of them fall inside the
/// image.
pub(crate) fn patch_median(
    g: &Gray,
    c: [f64; 2],
    e1: [f64; 2],
    e2: [f64; 2],
    half: f64,
    n: usize,
) -> Option<f32> {
    let mut v: [f32; 36] = [0.0; 36];
    let n = n.clamp(2, 6);
    let mut k = 0;
    for a in 0..n {
        let s = -half + 2.0 * half * a as f64 / (n - 1) as f64;
        for b in 0..n {
            let t = -half + 2.0 * half * b as f64 / (n - 1) as f64;
            let x = c[0] + s * e1[0] + t * e2[0];
            let y = c[1] + s * e1[1] + t * e2[1];
            if let Some(val) = g.bilinear(x, y) {
                v[k] = val;
                k += 1;
            }
        }
    }
    if 4 * k < 3 * n * n {
        return None;
    }
    let vals = &mut v[..k];
    let mid = k / 2;
    let (_, m, _) = vals.select_nth_unstable_by(mid, f32::total_cmp);
    Some(*m)
}

/// The two cells on either side of the link between sites `a` and `b` (4-neighbours):
/// `(cell on the +e side, cell on the -e side)`, where `e` is the lattice axis
/// perpendicular to the link.
pub(crate) fn link_cells(a: Coord, b: Coord) -> (Coord, Coord) {
    let lo = (a.0.min(b.0), a.1.min(b.1));
    if a.1 == b.1 {
        // link along i: cells above (+j) and below (-j)
        (lo, (lo.0, lo.1 - 1))
    } else {
        (lo, (lo.0 - 1, lo.1))
    }
}

/// Outcome of a colour check.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Check {
    Pass,
    Fail,
    Unknown,
}

/// A link between neighbouring sites `a` (at image `pa`) and `b` (at `pb`). `perp` is
/// the image vector of one lattice step along the axis perpendicular to the link, in
/// the direction of increasing coordinate.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Link {
    pub a: Coord,
    pub b: Coord,
    pub pa: [f64; 2],
    pub pb: [f64; 2],
    pub perp: [f64; 2],
}

/// Checks the link `link`: the cells on either side must have the colours of phase
/// `phase`, the dark one darker than the light one by at least `thr`.
pub(crate) fn check_link(g: &Gray, link: &Link, phase: u8, thr: f32) -> Check {
    let Link { a, b, pa, pb, perp } = *link;
    let (plus, _) = link_cells(a, b);
    let mid = [0.5 * (pa[0] + pb[0]), 0.5 * (pa[1] + pb[1])];
    let along = [pb[0] - pa[0], pb[1] - pa[1]];
    let centre = |s: f64| [mid[0] + s * 0.5 * perp[0], mid[1] + s * 0.5 * perp[1]];
    let (Some(vp), Some(vm)) = (
        patch_median(g, centre(1.0), along, perp, 0.2, 4),
        patch_median(g, centre(-1.0), along, perp, 0.2, 4),
    ) else {
        return Check::Unknown;
    };
    let (dark, light) = if cell_dark(plus.0, plus.1, phase) {
        (vp, vm)
    } else {
        (vm, vp)
    };
    if light - dark >= thr {
        Check::Pass
    } else if dark - light >= thr {
        Check::Fail
    } else {
        Check::Unknown
    }
}

/// Colour phase of a grid from the cells on both sides of every link: `Some((phase,
/// agreeing, disagreeing))` by majority over the links whose two cells differ by at
/// least `thr`; `None` when no link is decided.
pub(crate) fn phase_of(
    g: &Gray,
    at: &CoordMap<usize>,
    pos: &[[f64; 2]],
    thr: impl Fn(usize, usize) -> f32,
) -> Option<(u8, usize, usize)> {
    let (mut votes0, mut votes1) = (0usize, 0usize);
    for (&a, &ka) in at {
        for d in [(1, 0), (0, 1)] {
            let b = (a.0 + d.0, a.1 + d.1);
            let Some(&kb) = at.get(&b) else { continue };
            // perpendicular step from the neighbours on either side
            let q = if d.0 == 1 {
                (a.0, a.1 + 1)
            } else {
                (a.0 + 1, a.1)
            };
            let q2 = if d.0 == 1 {
                (a.0, a.1 - 1)
            } else {
                (a.0 - 1, a.1)
            };
            let (pa, pb) = (pos[ka], pos[kb]);
            let perp = match (at.get(&q), at.get(&q2)) {
                (Some(&kq), _) => [pos[kq][0] - pa[0], pos[kq][1] - pa[1]],
                (None, Some(&kq)) => [pa[0] - pos[kq][0], pa[1] - pos[kq][1]],
                // a quarter turn of the link, with the handedness of the other links
                // unknown: skip
                _ => continue,
            };
            let t = thr(ka, kb);
            match check_link(g, &Link { a, b, pa, pb, perp }, 0, t) {
                Check::Pass => votes0 += 1,
                Check::Fail => votes1 += 1,
                Check::Unknown => {}
            }
        }
    }
    if votes0 + votes1 == 0 {
        return None;
    }
    Some(if votes0 >= votes1 {
        (0, votes0, votes1)
    } else {
        (1, votes1, votes0)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_ignores_a_thin_line() {
        let (w, h) = (30, 30);
        let mut px = vec![40f32; w * h];
        for y in 0..h {
            px[y * w + 15] = 250.0;
        }
        let g = Gray { w, h, px };
        let m = patch_median(&g, [15.0, 15.0], [10.0, 0.0], [0.0, 10.0], 0.4, 5).unwrap();
        assert_eq!(m, 40.0);
        assert!(patch_median(&g, [0.0, 0.0], [10.0, 0.0], [0.0, 10.0], 0.4, 5).is_none());
    }

    #[test]
    fn link_cells_are_beside_the_link() {
        assert_eq!(link_cells((2, 3), (3, 3)), ((2, 3), (2, 2)));
        assert_eq!(link_cells((3, 3), (2, 3)), ((2, 3), (2, 2)));
        assert_eq!(link_cells((2, 3), (2, 4)), ((2, 3), (1, 3)));
    }
}
