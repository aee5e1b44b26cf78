//! Board indices for a grown grid: `(col, row) = R_k (i, j) + t`, a quarter-turn
//! rotation `R_k` of a right-handed lattice (mirror images are never labellings) and a
//! translation, chosen so that
//!
//! 1. every corner lies on the board,
//! 2. the square colours match (square `(a, b)` of the board is dark when `a + b` is
//!    even, spec/DATASET.md), and
//! 3. every side that provably ends at the board's outer squares ([`Side::End`]) lies on
//!    the board's edge.
//!
//! The labellings that pass form unions of orbits of the board's symmetries (a symmetry
//! keeps all three conditions). Exactly one orbit is accepted: one labelling is returned
//! and the symmetries go to `alternatives`. More than one orbit (a partial grid that
//! could sit at several places) or none (a board of another size, a mirror image,
//! colours that do not fit) is an error that says what was seen.

use crate::error::{Error, Result};
use crate::model::board::{Board, Symmetry};

use super::edges::Side;

/// `(col, row) = R_k (i, j) + t`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) struct Labelling {
    pub k: u8,
    pub t: (i64, i64),
}

#[inline]
pub(crate) fn rot(k: u8, (i, j): (i64, i64)) -> (i64, i64) {
    match k % 4 {
        0 => (i, j),
        1 => (-j, i),
        2 => (-i, -j),
        _ => (j, -i),
    }
}

impl Labelling {
    /// Board `(col, row)` of lattice site `(i, j)` (may lie off the board).
    pub fn apply(&self, i: i32, j: i32) -> (i64, i64) {
        let (a, b) = rot(self.k, (i as i64, j as i64));
        (a + self.t.0, b + self.t.1)
    }

    /// Lattice site of board `(col, row)`.
    pub fn inverse(&self, col: i64, row: i64) -> (i32, i32) {
        let (i, j) = rot((4 - self.k % 4) % 4, (col - self.t.0, row - self.t.1));
        (i as i32, j as i32)
    }

    /// This labelling followed by the board symmetry `s`.
    fn then(&self, s: &Symmetry) -> Labelling {
        let (a, b) = rot(s.quarter_turns, self.t);
        Labelling {
            k: (self.k + s.quarter_turns) % 4,
            t: (a + s.shift.0, b + s.shift.1),
        }
    }
}

/// What the labelling needs from the grid.
pub(crate) struct GridView<'a> {
    /// Lattice extent `(imin, imax, jmin, jmax)`.
    pub ext: (i32, i32, i32, i32),
    /// Colour phase: lattice cell `(i, j)` is dark iff `i + j + phase` is even.
    pub phase: u8,
    /// Sides in the order of `edges::OUTWARD` (`-i, +i, -j, +j`).
    pub sides: [Side; 4],
    /// Image directions of `+i` and `+j` (a right-handed lattice: `cross(di, dj) > 0`).
    pub di: [f64; 2],
    pub dj: [f64; 2],
    /// Sites of the grid (for the "on the board" test).
    pub sites: &'a [(i32, i32)],
}

fn on_board(board: &Board, (c, r): (i64, i64)) -> bool {
    c >= 0 && r >= 0 && c < board.cols as i64 && r < board.rows as i64
}

/// Every labelling that satisfies conditions 1-3 (module docs).
pub(crate) fn candidates(board: &Board, g: &GridView) -> Vec<Labelling> {
    let (imin, imax, jmin, jmax) = g.ext;
    let mut out = Vec::new();
    for k in 0..4u8 {
        let corners = [(imin, jmin), (imin, jmax), (imax, jmin), (imax, jmax)]
            .map(|(i, j)| rot(k, (i as i64, j as i64)));
        let lo = (
            corners.iter().map(|c| c.0).min().unwrap_or(0),
            corners.iter().map(|c| c.1).min().unwrap_or(0),
        );
        let hi = (
            corners.iter().map(|c| c.0).max().unwrap_or(0),
            corners.iter().map(|c| c.1).max().unwrap_or(0),
        );
        for tx in -lo.0..=(board.cols as i64 - 1 - hi.0) {
            for ty in -lo.1..=(board.rows as i64 - 1 - hi.1) {
                let l = Labelling { k, t: (tx, ty) };
                // colours: the cell at (imin, jmin), doubled coordinates of its centre
                let (x, y) = rot(k, (2 * imin as i64 + 1, 2 * jmin as i64 + 1));
                let (x, y) = (x + 2 * tx, y + 2 * ty);
                let board_dark = ((x - 1) / 2 + (y - 1) / 2).rem_euclid(2) == 0;
                let seen_dark = (imin as i64 + jmin as i64 + g.phase as i64).rem_euclid(2) == 0;
                if board_dark != seen_dark {
                    continue;
                }
                if !g.sites.iter().all(|&(i, j)| on_board(board, l.apply(i, j))) {
                    continue;
                }
                let ends_ok =
                    (0..4).all(|s| g.sides[s] != Side::End || !on_board(board, outward(&l, g, s)));
                if ends_ok {
                    out.push(l);
                }
            }
        }
    }
    out
}

/// Board position of the site one step outwards from the middle of side `s`.
fn outward(l: &Labelling, g: &GridView, s: usize) -> (i64, i64) {
    let (imin, imax, jmin, jmax) = g.ext;
    let site = match s {
        0 => (imin - 1, jmin),
        1 => (imax + 1, jmin),
        2 => (imin, jmin - 1),
        _ => (imin, jmax + 1),
    };
    l.apply(site.0, site.1)
}

const SIDE_NAMES: [&str; 4] = ["-i", "+i", "-j", "+j"];

/// The labelling of the grid, and the board symmetries that give the others.
pub(crate) fn label(
    board: &Board,
    g: &GridView,
    mirrored: &GridView,
) -> Result<(Labelling, Vec<Symmetry>)> {
    let (imin, imax, jmin, jmax) = g.ext;
    let (ni, nj) = (imax - imin + 1, jmax - jmin + 1);
    let ends = g.sides.iter().filter(|s| **s == Side::End).count();
    let seen = format!(
        "a grid of {ni} x {nj} corners ({} sites; sides ending at the board's outer squares: {ends} of 4)",
        g.sites.len()
    );
    let want = format!(
        "rig.json's board has {} rows x {} cols of inner corners",
        board.rows, board.cols
    );
    let v = candidates(board, g);
    if v.is_empty() {
        let fits = |a: i32, b: i32| a as usize <= board.cols && b as usize <= board.rows;
        let msg = if !fits(ni, nj) && !fits(nj, ni) {
            format!("found {seen}, more than the board has: {want}")
        } else if !candidates(board, mirrored).is_empty() {
            format!("found {seen} that fits the board only as a mirror image (seen from behind): {want}")
        } else if ends == 4 {
            format!("found a complete chessboard of {ni} x {nj} corners (the squares end on all four sides): {want}")
        } else {
            format!(
                "found {seen} whose square colours and ends fit no placement on the board: {want}"
            )
        };
        return Err(Error::Detection(msg));
    }
    let syms = board.symmetries();
    let first = v[0];
    let mut orbit: Vec<Labelling> = vec![first];
    orbit.extend(syms.iter().map(|s| first.then(s)));
    let same_orbit = v.len() == orbit.len() && v.iter().all(|l| orbit.contains(l));
    if !same_orbit {
        let (vc, vr) = if first.k % 2 == 0 { (ni, nj) } else { (nj, ni) };
        let what = match (vc as usize == board.cols, vr as usize == board.rows) {
            (false, true) => format!("only {vc} of {} columns of corners are visible", board.cols),
            (true, false) => format!("only {vr} of {} rows of corners are visible", board.rows),
            _ => format!(
                "only {vc} of {} columns and {vr} of {} rows of corners are visible",
                board.cols, board.rows
            ),
        };
        return Err(Error::Detection(format!(
            "{what} and nothing fixes which ({} placements on the board fit {seen})",
            v.len() / orbit.len().max(1)
        )));
    }
    // squares that go on beyond a side the labelling puts at the board's edge
    for (s, name) in SIDE_NAMES.iter().enumerate() {
        if g.sides[s] == Side::Continues && !on_board(board, outward(&first, g, s)) {
            return Err(Error::Detection(format!(
                "found {seen}: squares continue beyond its {} side, where the board ends: the board in \
                 the image is larger than {want}, or its corners there were missed",
                name
            )));
        }
    }
    // within the orbit: +col pointing most along +u, then the fewest quarter turns
    let score = |l: &Labelling| {
        let (a, b) = rot((4 - l.k % 4) % 4, (1, 0));
        let d = [
            a as f64 * g.di[0] + b as f64 * g.dj[0],
            a as f64 * g.di[1] + b as f64 * g.dj[1],
        ];
        d[0] / (d[0].hypot(d[1])).max(1e-12)
    };
    let mut best = first;
    for l in &orbit {
        let (sb, sl) = (score(&best), score(l));
        if sl > sb + 1e-9 || ((sl - sb).abs() <= 1e-9 && l.k < best.k) {
            best = *l;
        }
    }
    Ok((best, syms))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn full(ni: i32, nj: i32) -> Vec<(i32, i32)> {
        (0..ni).flat_map(|i| (0..nj).map(move |j| (i, j))).collect()
    }

    fn view(
        sites: &[(i32, i32)],
        ext: (i32, i32, i32, i32),
        phase: u8,
        sides: [Side; 4],
    ) -> GridView<'_> {
        GridView {
            ext,
            phase,
            sides,
            di: [1.0, 0.0],
            dj: [0.0, 1.0],
            sites,
        }
    }

    #[test]
    fn complete_grid_is_labelled_by_colour() {
        let b = Board::chessboard(6, 9, 20.0).unwrap();
        let s = full(9, 6);
        let u = [Side::Unknown; 4];
        // phase 0: cell (0, 0) dark; the board's square (0, 0) is dark: identity
        let (l, syms) = label(
            &b,
            &view(&s, (0, 8, 0, 5), 0, u),
            &view(&s, (0, 5, 0, 8), 0, u),
        )
        .unwrap();
        assert_eq!(l, Labelling { k: 0, t: (0, 0) });
        assert!(syms.is_empty());
        // swapped colours: the half turn
        let (l, _) = label(
            &b,
            &view(&s, (0, 8, 0, 5), 1, u),
            &view(&s, (0, 5, 0, 8), 1, u),
        )
        .unwrap();
        assert_eq!(l, Labelling { k: 2, t: (8, 5) });
        assert_eq!(l.apply(0, 0), (8, 5));
        assert_eq!(l.inverse(8, 5), (0, 0));
    }

    #[test]
    fn partial_grid_needs_an_end() {
        let b = Board::chessboard(6, 9, 20.0).unwrap();
        let s = full(7, 6);
        let u = [Side::Unknown; 4];
        let e = label(
            &b,
            &view(&s, (0, 6, 0, 5), 0, u),
            &view(&s, (0, 5, 0, 6), 0, u),
        )
        .unwrap_err();
        assert!(e.to_string().contains("only 7 of 9 columns"), "{e}");
        let mut sides = u;
        sides[0] = Side::End;
        let (l, _) = label(
            &b,
            &view(&s, (0, 6, 0, 5), 0, sides),
            &view(&s, (0, 5, 0, 6), 0, sides),
        )
        .unwrap();
        assert_eq!(l.apply(0, 0), (0, 0));
        // the other end: colours say the grid's cell (0, 0) is light there
        let mut sides = u;
        sides[1] = Side::End;
        let (l, _) = label(
            &b,
            &view(&s, (0, 6, 0, 5), 0, sides),
            &view(&s, (0, 5, 0, 6), 0, sides),
        )
        .unwrap();
        assert_eq!(l.apply(6, 0), (8, 0));
    }

    #[test]
    fn wrong_sizes_say_what_was_found() {
        let b = Board::chessboard(6, 8, 20.0).unwrap();
        let s = full(9, 6);
        let u = [Side::Unknown; 4];
        let e = label(
            &b,
            &view(&s, (0, 8, 0, 5), 0, u),
            &view(&s, (0, 5, 0, 8), 0, u),
        )
        .unwrap_err();
        assert!(e.to_string().contains("9 x 6"), "{e}");
        let b = Board::chessboard(6, 10, 20.0).unwrap();
        let e = label(
            &b,
            &view(&s, (0, 8, 0, 5), 0, [Side::End; 4]),
            &view(&s, (0, 5, 0, 8), 0, [Side::End; 4]),
        )
        .unwrap_err();
        assert!(
            e.to_string().contains("complete chessboard of 9 x 6"),
            "{e}"
        );
    }

    #[test]
    fn symmetric_board_gives_alternatives() {
        let b = Board::chessboard(6, 8, 20.0).unwrap();
        let s = full(8, 6);
        let u = [Side::Unknown; 4];
        let (_, syms) = label(
            &b,
            &view(&s, (0, 7, 0, 5), 0, u),
            &view(&s, (0, 5, 0, 7), 0, u),
        )
        .unwrap();
        assert_eq!(syms.len(), 1);
        assert_eq!(syms[0].quarter_turns, 2);
    }
}
