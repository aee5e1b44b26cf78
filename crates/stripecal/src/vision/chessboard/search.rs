//! The search over pyramid levels: candidates and grids level by level, coarse to
//! fine, stopping at the first level whose grid has as many corners as the board.

use super::candidates::{self, Cand};
use super::grid::{self, Grid};
use super::image::Gray;
use super::lattice::CoordMap;

/// A grid found on some level, positions converted to full-resolution pixels.
#[derive(Debug, Clone)]
pub(crate) struct Found {
    pub level: usize,
    pub sites: CoordMap<[f64; 2]>,
    pub phase: u8,
    pub grown: usize,
    pub inconsistent: usize,
}

/// What the search saw, for messages.
#[derive(Debug, Clone, Default)]
pub(crate) struct SearchStats {
    /// Candidates per level searched (finest last).
    pub candidates: Vec<(usize, usize)>,
}

/// Settings of the search.
pub(crate) struct SearchOpts {
    pub min_response: f32,
    pub levels: usize,
    /// Corners of the board.
    pub board_len: usize,
    /// Largest extent of a grid in either lattice direction.
    pub max_extent: i32,
}

fn to_full(level: usize, p: [f64; 2]) -> [f64; 2] {
    let s = (1usize << level) as f64;
    [(p[0] + 0.5) * s - 0.5, (p[1] + 0.5) * s - 0.5]
}

fn found(level: usize, g: &Grid, cands: &[Cand]) -> Found {
    let sites =
        g.at.iter()
            .map(|(&t, &k)| (t, to_full(level, [cands[k].x as f64, cands[k].y as f64])))
            .collect();
    Found {
        level,
        sites,
        phase: g.phase,
        grown: g.grown,
        inconsistent: g.inconsistent,
    }
}

/// Grids over the pyramid of `g0` (noise sigma `noise` at full resolution): every grid
/// of every level searched, largest first.
pub(crate) fn search(g0: &Gray, noise: f32, o: &SearchOpts) -> (Vec<Found>, SearchStats) {
    let mut pyr: Vec<Gray> = Vec::new();
    for _ in 1..o.levels {
        let next = pyr.last().unwrap_or(g0).half();
        if next.w < 2 * candidates::MARGIN + 8 || next.h < 2 * candidates::MARGIN + 8 {
            break;
        }
        pyr.push(next);
    }
    let mut stats = SearchStats::default();
    let mut all: Vec<Found> = Vec::new();
    for level in (0..=pyr.len()).rev() {
        let g = if level == 0 { g0 } else { &pyr[level - 1] };
        let nl = noise / (1usize << level) as f32;
        let cands = candidates::find(g, o.min_response, 6.0 * nl, 6000);
        stats.candidates.push((level, cands.len()));
        let ctx = grid::Ctx::new(g, &cands, nl, o.max_extent);
        let grids = grid::find_grids(&ctx, 3);
        let complete = grids.first().is_some_and(|gr| gr.at.len() >= o.board_len);
        all.extend(grids.iter().map(|gr| found(level, gr, &cands)));
        if complete {
            break;
        }
    }
    // largest first; on ties the finer level
    all.sort_by(|a, b| {
        b.sites
            .len()
            .cmp(&a.sites.len())
            .then(a.level.cmp(&b.level))
    });
    (all, stats)
}
