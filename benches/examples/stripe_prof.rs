//! CPU time per image of `StripeExtractor::extract_into` on twin laser images, from the
//! on-CPU ns of the thread (/proc/thread-self/schedstat): time-sharing with other jobs
//! does not count. Linux only. See BENCHMARKS.md "Vision: stripes".
//!
//! Args: `CASES [SECONDS]` with CASES a comma list of
//! - `mem`, `cols`, `auto`, `rows_t`, `auto_t` (or `all`): the hp3-paper calibration
//!   view 0 (`rows_t`/`auto_t`: the transposed image);
//! - `scan`: the hp3-paper twin's scan frames (12 frames spread over the ball scan,
//!   cycled), extracted as `reconstruct_scan` does (the direction from the calibration's
//!   plane, default options: survey, smoothing where it finds speckle, chains, qualities);
//!
//! or one of
//! - `check`: cols on the view vs auto on the transposed view, bit for bit;
//! - `points FILE [REALDIR...]`: every point (all fields, bit patterns) of the scan frames
//!   and of the laser images of each real data set folder given (stripe direction from
//!   its rig.json, gray signal) into FILE, for before/after comparisons;
//! - `peer PYTHON PAIRS [SECONDS]`: ours on the scan frames against the numpy peer
//!   (`scripts/bench_stripe_numpy.py`: argmax + 3-point centroid per row) on the same
//!   frames, alternately, PAIRS times SECONDS each.
use std::hint::black_box;
use std::io::Write;
use stripecal::model::image::{AnyGray, AnyView, GrayImage, ImageView};
use stripecal::model::{StripeChannel, StripeDirection};
use stripecal::reconstruct::{ReconstructOptions, Reconstructor};
use stripecal::vision::stripe::{stripe_signal, StripeExtractor, StripeOptions, StripePoint};
use stripecal_sim::{SimConfig, Twin};

/// Scan frames taken from the ball scan.
const SCAN_FRAMES: usize = 12;

fn cpu_ns() -> u64 {
    let s = std::fs::read_to_string("/proc/thread-self/schedstat").unwrap();
    s.split_whitespace().next().unwrap().parse().unwrap()
}
fn transpose(i: &GrayImage<u8>) -> GrayImage<u8> {
    let mut o = GrayImage::new(i.height, i.width);
    for y in 0..i.height {
        for x in 0..i.width {
            o.data[x * i.height + y] = i.data[y * i.width + x];
        }
    }
    o
}

/// `(min, median)` CPU us per call of `f` over slices of 0.25 s for `secs` seconds
/// (`f` does `per` images a call).
fn time(secs: f64, per: usize, f: &mut dyn FnMut()) -> (f64, f64) {
    let mut all = Vec::new();
    let reps = (secs / 0.25).ceil().max(1.0) as usize;
    for _ in 0..reps {
        let t0 = cpu_ns();
        let mut n = 0u64;
        while cpu_ns() - t0 < 250_000_000 {
            for _ in 0..4 {
                f();
            }
            n += 4;
        }
        all.push((cpu_ns() - t0) as f64 / (n as usize * per) as f64 / 1e3);
    }
    all.sort_by(|a, b| a.partial_cmp(b).unwrap());
    (all[0], all[all.len() / 2])
}

/// The twin's scan frames (8-bit) and the direction `reconstruct_scan` extracts them in.
fn scan_frames(twin: &Twin) -> (Vec<GrayImage<u8>>, StripeDirection) {
    let qs = twin.scan_poses().unwrap();
    let frames = (0..SCAN_FRAMES)
        .map(|i| {
            let k = (2 * i + 1) * qs.len() / (2 * SCAN_FRAMES);
            match twin.render_scan_frame(&qs[k], k).unwrap().laser_image {
                Some(AnyGray::U8(g)) => g,
                _ => panic!("expected an 8-bit laser image"),
            }
        })
        .collect();
    let cal = twin.true_calibration();
    let rec = Reconstructor::new(&cal, &ReconstructOptions::default()).unwrap();
    (frames, rec.direction())
}

/// Writes `img` as a `.npy` file (uint8, C order).
fn write_npy(path: &std::path::Path, img: &GrayImage<u8>) {
    let mut header = format!(
        "{{'descr': '|u1', 'fortran_order': False, 'shape': ({}, {}), }}",
        img.height, img.width
    );
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut f = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    f.write_all(b"\x93NUMPY\x01\x00").unwrap();
    f.write_all(&(header.len() as u16).to_le_bytes()).unwrap();
    f.write_all(header.as_bytes()).unwrap();
    f.write_all(&img.data).unwrap();
}

fn point_line(tag: &str, p: &StripePoint) -> String {
    format!(
        "{tag} {:016x} {:016x} {:08x} {:08x} {:08x} {} | {:.6} {:.6} {:.3} {:.3}\n",
        p.u.to_bits(),
        p.v.to_bits(),
        p.peak.to_bits(),
        p.width_px.to_bits(),
        p.support_px.to_bits(),
        p.flags,
        p.u,
        p.v,
        p.peak,
        p.width_px
    )
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let which = args.get(1).cloned().unwrap_or("all".into());
    let twin = Twin::new(SimConfig::hp3_paper()).unwrap();
    if which == "points" {
        let out_path = &args[2];
        let mut out = String::new();
        let (frames, dir) = scan_frames(&twin);
        let mut ex = StripeExtractor::new(StripeOptions {
            direction: dir,
            ..Default::default()
        })
        .unwrap();
        let mut pts = Vec::new();
        for (i, f) in frames.iter().enumerate() {
            ex.extract_into(
                AnyView::U8(ImageView::from_slice(&f.data, f.width, f.height).unwrap()),
                &mut pts,
            )
            .unwrap();
            out += &format!(
                "# scan frame {i}: {} points {:?} {:?} along {:?}\n",
                pts.len(),
                ex.rejected(),
                ex.survey(),
                ex.adapted()
            );
            for p in &pts {
                out += &point_line(&format!("s{i}"), p);
            }
        }
        for dir in &args[3..] {
            let root = std::path::Path::new(dir);
            let rig: serde_json::Value =
                serde_json::from_str(&std::fs::read_to_string(root.join("rig.json")).unwrap())
                    .unwrap();
            let direction = match rig["stripe"]["direction"].as_str() {
                Some("rows") => StripeDirection::Rows,
                Some("cols") => StripeDirection::Cols,
                _ => StripeDirection::Auto,
            };
            let mut names: Vec<_> = std::fs::read_dir(root.join("images"))
                .unwrap()
                .map(|e| e.unwrap().path())
                .collect();
            names.sort();
            // the rig's direction, then the other one (a line across the scan lines:
            // many peaks per scan line, the chains' work)
            let other = if direction == StripeDirection::Rows {
                StripeDirection::Cols
            } else {
                StripeDirection::Rows
            };
            let runs = [direction, other];
            for (p, direction) in names
                .iter()
                .flat_map(|p| runs.iter().map(move |d| (p.clone(), *d)))
            {
                let opts = StripeOptions {
                    direction,
                    ..Default::default()
                };
                let mut ex = StripeExtractor::new(opts.clone()).unwrap();
                let img = stripecal::io::load_image(&p).unwrap();
                let sig = stripe_signal(&img, StripeChannel::Gray, &opts).unwrap();
                let d = ex.extract_into(sig.view().unwrap(), &mut pts).unwrap();
                let name = p.file_name().unwrap().to_string_lossy().to_string();
                out += &format!(
                    "# {dir}/{name} {d:?}: {} points {:?} {:?} along {:?}\n",
                    pts.len(),
                    ex.rejected(),
                    ex.survey(),
                    ex.adapted()
                );
                for q in &pts {
                    out += &point_line(&name, q);
                }
            }
        }
        std::fs::write(out_path, out).unwrap();
        return;
    }
    if which == "peer" {
        let python = &args[2];
        let pairs: usize = args.get(3).map_or(6, |s| s.parse().unwrap());
        let secs: f64 = args.get(4).map_or(1.0, |s| s.parse().unwrap());
        let (frames, dir) = scan_frames(&twin);
        let tmp = std::env::temp_dir().join(format!("stripe_prof_{}", std::process::id()));
        std::fs::create_dir_all(&tmp).unwrap();
        for (i, f) in frames.iter().enumerate() {
            write_npy(&tmp.join(format!("frame{i:02}.npy")), f);
        }
        let script = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../scripts/bench_stripe_numpy.py"
        );
        let mut ex = StripeExtractor::new(StripeOptions {
            direction: dir,
            ..Default::default()
        })
        .unwrap();
        let mut out = Vec::new();
        let views: Vec<AnyView> = frames
            .iter()
            .map(|f| AnyView::U8(ImageView::from_slice(&f.data, f.width, f.height).unwrap()))
            .collect();
        let mut n_pts = 0;
        for v in &views {
            ex.extract_into(*v, &mut out).unwrap();
            n_pts += out.len();
        }
        println!(
            "{} scan frames {}x{}, direction {dir:?}, {:.0} points per frame",
            frames.len(),
            frames[0].width,
            frames[0].height,
            n_pts as f64 / frames.len() as f64
        );
        let (mut ours, mut peer) = (Vec::new(), Vec::new());
        for pair in 0..pairs {
            let (mn, md) = time(secs, views.len(), &mut || {
                for v in &views {
                    ex.extract_into(black_box(*v), &mut out).unwrap();
                }
            });
            let o = std::process::Command::new(python)
                .arg(script)
                .arg(&tmp)
                .arg(secs.to_string())
                .arg(if dir == StripeDirection::Rows {
                    "rows"
                } else {
                    "cols"
                })
                .output()
                .unwrap();
            let s = String::from_utf8_lossy(&o.stdout);
            let mut it = s.split_whitespace().map(|t| t.parse::<f64>().unwrap());
            let (pmn, pmd) = (it.next().unwrap(), it.next().unwrap());
            println!(
                "pair {pair}: stripecal cpu min {mn:6.1} median {md:6.1} us/frame | numpy min \
                 {pmn:6.1} median {pmd:6.1} | ratio of medians (numpy/ours) {:.2}",
                pmd / md
            );
            ours.push(md);
            peer.push(pmd);
        }
        let med = |v: &mut Vec<f64>| {
            v.sort_by(|a, b| a.partial_cmp(b).unwrap());
            v[v.len() / 2]
        };
        let (o, p) = (med(&mut ours), med(&mut peer));
        println!(
            "median over pairs: stripecal {o:.1} us/frame ({:.0}/s), numpy {p:.1} us/frame \
             ({:.0}/s): ours takes {:.2}x numpy's time",
            1e6 / o,
            1e6 / p,
            o / p
        );
        std::fs::remove_dir_all(&tmp).ok();
        return;
    }
    let secs: f64 = args.get(2).map(|s| s.parse().unwrap()).unwrap_or(3.0);
    let poses = twin.calibration_poses().unwrap();
    let view = twin.render_view(&poses[0].q_deg, 0).unwrap();
    let Some(AnyGray::U8(laser)) = view.laser_image else {
        panic!()
    };
    let lt = AnyGray::U8(transpose(&laser));
    let bytes = laser.data.clone();
    let laser = AnyGray::U8(laser);
    let img = laser.view().unwrap();
    let img_t = lt.view().unwrap();
    let wanted = |name: &str| which == "all" || which.split(',').any(|w| w == name);
    let report = |name: &str, (best, med): (f64, f64)| {
        println!(
            "{name:10} cpu min {best:7.1} us/img  median {med:7.1}  ({:.0}/s at min)",
            1e6 / best
        );
    };
    if which == "check" {
        let mut a = StripeExtractor::new(StripeOptions {
            direction: StripeDirection::Cols,
            ..Default::default()
        })
        .unwrap();
        let mut b = StripeExtractor::new(StripeOptions::default()).unwrap();
        let (mut pa, mut pb) = (Vec::new(), Vec::new());
        a.extract_into(img, &mut pa).unwrap();
        let d = b.extract_into(img_t, &mut pb).unwrap();
        let mut maxd = 0f64;
        let mut neq = 0;
        for (p, q) in pa.iter().zip(&pb) {
            maxd = maxd.max((p.u - q.v).abs()).max((p.v - q.u).abs());
            if p.u != q.v
                || p.v != q.u
                || p.peak != q.peak
                || p.width_px != q.width_px
                || p.flags != q.flags
                || p.support_px != q.support_px
            {
                neq += 1;
            }
        }
        println!(
            "dir {d:?} n {} {} maxdiff {maxd:e} unequal {neq}",
            pa.len(),
            pb.len()
        );
        return;
    }
    if wanted("mem") {
        report(
            "mem",
            time(secs, 1, &mut || {
                black_box(
                    black_box(&bytes)
                        .iter()
                        .fold(0u32, |a, &v| a.wrapping_add(v as u32)),
                );
            }),
        );
    }
    for (name, dir, v) in [
        ("cols", StripeDirection::Cols, img),
        ("auto", StripeDirection::Auto, img),
        ("rows_t", StripeDirection::Rows, img_t),
        ("auto_t", StripeDirection::Auto, img_t),
    ] {
        if !wanted(name) {
            continue;
        }
        let mut ex = StripeExtractor::new(StripeOptions {
            direction: dir,
            ..Default::default()
        })
        .unwrap();
        let mut out = Vec::new();
        report(
            name,
            time(secs, 1, &mut || {
                ex.extract_into(black_box(v), &mut out).unwrap();
            }),
        );
    }
    if wanted("scan") {
        let (frames, dir) = scan_frames(&twin);
        let views: Vec<AnyView> = frames
            .iter()
            .map(|f| AnyView::U8(ImageView::from_slice(&f.data, f.width, f.height).unwrap()))
            .collect();
        let mut ex = StripeExtractor::new(StripeOptions {
            direction: dir,
            ..Default::default()
        })
        .unwrap();
        let mut out = Vec::new();
        report(
            "scan",
            time(secs, views.len(), &mut || {
                for v in &views {
                    ex.extract_into(black_box(*v), &mut out).unwrap();
                }
            }),
        );
    }
}
