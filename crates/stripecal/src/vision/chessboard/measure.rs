//! Full-resolution measurement of a grid: every site refined, inconsistent sites
//! removed, then the grid extended site by site (and across one hidden line) wherever
//! the lattice predicts a corner that the refinement confirms.

use super::image::Gray;
use super::lattice::{cell_dark, extent, predict_any, Coord, CoordMap, CoordSet, Local};
use super::refine::{refine, Fail, Saddle, Settings};

/// Measured sites and the sites that could not be measured.
pub(crate) struct Measured {
    /// Site -> index into `pts` / `pos`.
    pub at: CoordMap<usize>,
    pub pts: Vec<Saddle>,
    pub pos: Vec<[f64; 2]>,
    /// Sites tried without success, with the reason and the predicted position.
    pub failed: CoordMap<(Fail, [f64; 2])>,
}

const DIRS: [Coord; 4] = [(1, 0), (-1, 0), (0, 1), (0, -1)];

impl Measured {
    fn insert(&mut self, t: Coord, s: Saddle) {
        self.failed.remove(&t);
        match self.at.get(&t) {
            Some(&k) => {
                self.pts[k] = s;
                self.pos[k] = [s.u, s.v];
            }
            None => {
                self.at.insert(t, self.pts.len());
                self.pts.push(s);
                self.pos.push([s.u, s.v]);
            }
        }
    }

    /// Moves the measured `sites` to the failed ones with the reason `why`.
    fn fail_sites(&mut self, sites: Vec<Coord>, why: &'static str) {
        for t in sites {
            if let Some(k) = self.at.remove(&t) {
                self.failed.insert(t, (Fail::NotCorner(why), self.pos[k]));
            }
        }
    }

    /// Drops sites their neighbours do not predict within `tol` pitches.
    fn prune(&mut self, tol: f64) {
        let mut at = self.at.clone();
        super::grid::leave_one_out(&mut at, &self.pos, tol);
        let gone: Vec<Coord> = self
            .at
            .keys()
            .filter(|t| !at.contains_key(t))
            .copied()
            .collect();
        self.fail_sites(gone, "inconsistent with its neighbours");
    }

    /// Drops sites without a measured 4-neighbour (a jump across a failed site that
    /// nothing around confirms).
    fn drop_isolated(&mut self) {
        let lone: Vec<Coord> = self
            .at
            .keys()
            .filter(|t| {
                !DIRS
                    .iter()
                    .any(|d| self.at.contains_key(&(t.0 + d.0, t.1 + d.1)))
            })
            .copied()
            .collect();
        self.fail_sites(lone, "no measured corner next to it");
    }

    /// Local lattice at `t` from the measured sites.
    pub fn local(&self, t: Coord) -> Option<Local> {
        predict_any(&self.at, &self.pos, t)
    }
}

/// Refines site `t` starting at `l.p` with the local lattice steps `l.di`, `l.dj`; the
/// contrast must be at least 40 % of the median of the measured sites within two steps
/// (a corner of the same board under nearly the same light).
pub(crate) fn measure_site(
    g: &Gray,
    m: &Measured,
    t: Coord,
    l: &Local,
    phase: u8,
    strict: bool,
    s: &Settings,
) -> Result<Saddle, Fail> {
    let mut near: Vec<f64> = Vec::new();
    let mut blur: Vec<f64> = Vec::new();
    for di in -2..=2 {
        for dj in -2..=2 {
            if let Some(&k) = m.at.get(&(t.0 + di, t.1 + dj)) {
                near.push(m.pts[k].contrast);
                blur.push(m.pts[k].ln_blur);
            }
        }
    }
    // the fit starts from the median blur of those sites (0 without them)
    blur.sort_by(f64::total_cmp);
    let s = &Settings {
        ln_blur0: blur.get(blur.len() / 2).copied().unwrap_or(0.0),
        ..*s
    };
    let sd = refine(
        g,
        l.p,
        l.di,
        l.dj,
        Some(!cell_dark(t.0, t.1, phase)),
        strict,
        s,
    )?;
    if !near.is_empty() {
        near.sort_by(f64::total_cmp);
        if sd.contrast < 0.4 * near[near.len() / 2] {
            return Err(Fail::NotCorner(
                "too little contrast compared with the corners around it",
            ));
        }
    }
    Ok(sd)
}

fn inside(g: &Gray, p: [f64; 2]) -> bool {
    p[0] >= 0.0 && p[1] >= 0.0 && p[0] <= (g.w - 1) as f64 && p[1] <= (g.h - 1) as f64
}

/// Measures the coarse grid `coarse` (full-resolution positions) and extends it;
/// `cap` bounds the extent in either lattice direction.
pub(crate) fn measure_grid(
    g: &Gray,
    coarse: &CoordMap<[f64; 2]>,
    phase: u8,
    s: &Settings,
    cap: i32,
) -> Measured {
    let mut keys: Vec<Coord> = coarse.keys().copied().collect();
    keys.sort_unstable();
    let cpos: Vec<[f64; 2]> = keys.iter().map(|t| coarse[t]).collect();
    let cat: CoordMap<usize> = keys.iter().enumerate().map(|(k, &t)| (t, k)).collect();
    let mut m = Measured {
        at: CoordMap::default(),
        pts: Vec::new(),
        pos: Vec::new(),
        failed: CoordMap::default(),
    };
    for (k, &t) in keys.iter().enumerate() {
        let Some(l) = predict_any(&cat, &cpos, t) else {
            continue;
        };
        match measure_site(g, &m, t, &Local { p: cpos[k], ..l }, phase, false, s) {
            Ok(sd) => m.insert(t, sd),
            Err(f) => {
                m.failed.insert(t, (f, cpos[k]));
            }
        }
    }
    m.prune(0.15);
    extend(g, &mut m, phase, s, cap);
    m.prune(0.15);
    m.drop_isolated();
    m
}

/// Grows the measured grid: free sites next to it, and sites two steps out beyond a
/// site that failed (a line hidden by a stripe).
fn extend(g: &Gray, m: &mut Measured, phase: u8, s: &Settings, cap: i32) {
    let mut tried: CoordSet = m.failed.keys().copied().collect();
    for _round in 0..64 {
        let mut targets: Vec<Coord> = Vec::new();
        for &t in m.at.keys() {
            for d in DIRS {
                let n = (t.0 + d.0, t.1 + d.1);
                if !m.at.contains_key(&n) && !tried.contains(&n) {
                    targets.push(n);
                } else if matches!(
                    m.failed.get(&n),
                    Some((Fail::Stripe | Fail::NotCorner(_), _))
                ) {
                    let n2 = (t.0 + 2 * d.0, t.1 + 2 * d.1);
                    if !m.at.contains_key(&n2) && !tried.contains(&n2) {
                        targets.push(n2);
                    }
                }
            }
        }
        targets.sort_unstable();
        targets.dedup();
        let Some(ext) = extent(m.at.keys()) else {
            return;
        };
        targets.retain(|t| {
            ext.1.max(t.0) - ext.0.min(t.0) < cap && ext.3.max(t.1) - ext.2.min(t.1) < cap
        });
        let mut added = 0;
        for t in targets {
            let Some(l) = m.local(t) else { continue };
            tried.insert(t);
            if !inside(g, l.p) {
                continue;
            }
            match measure_site(g, m, t, &l, phase, true, s) {
                Ok(sd) => {
                    m.insert(t, sd);
                    added += 1;
                }
                Err(f) => {
                    m.failed.insert(t, (f, l.p));
                }
            }
        }
        if added == 0 {
            return;
        }
    }
}

/// Tries the board sites that the grid has not measured yet and whose predicted
/// position lies in the image (holes); returns the sites newly measured or failed.
pub(crate) fn fill(g: &Gray, m: &mut Measured, sites: &[Coord], phase: u8, s: &Settings) {
    for &t in sites {
        if m.at.contains_key(&t) || m.failed.contains_key(&t) {
            continue;
        }
        let Some(l) = m.local(t) else { continue };
        if !inside(g, l.p) {
            continue;
        }
        match measure_site(g, m, t, &l, phase, true, s) {
            Ok(sd) => m.insert(t, sd),
            Err(f) => {
                m.failed.insert(t, (f, l.p));
            }
        }
    }
}
