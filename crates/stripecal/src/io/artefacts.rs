//! `artefacts.json` (spec/DATASET.md "Verification artefacts"): typed errors name the
//! file and the key.

use std::collections::HashSet;
use std::path::Path;

use super::atomic::read_text;
use super::json::{parse, Obj};
use crate::error::Result;
use crate::model::artefacts::{
    ArtefactPlane, ArtefactSphere, Artefacts, BallBar, CertificateUncertainty, Mpe,
};

/// Reads `artefacts.json`.
pub fn read_artefacts(path: impl AsRef<Path>) -> Result<Artefacts> {
    let path = path.as_ref();
    let text = read_text(path)?;
    let v = parse(path, &text)?;
    let o = Obj::root(path, &v)?;
    o.check_format("stripecal/artefacts@1")?;
    let list = |key: &str| -> Result<Vec<Obj<'_>>> {
        match o.opt(key) {
            None => Ok(vec![]),
            Some(a) => a.arr()?.iter().map(|x| x.obj()).collect(),
        }
    };
    let mut names = HashSet::new();
    let mut spheres = Vec::new();
    for s in list("spheres")? {
        let name = s.req("name")?.str()?.to_string();
        if !names.insert(name.clone()) {
            return Err(s.err(format!("sphere name {name:?} is used twice")));
        }
        spheres.push(ArtefactSphere {
            name,
            diameter_mm: s.positive_f64("diameter_mm")?,
            form_mm: s
                .opt("form_mm")
                .map(|v| v.nonneg_f64())
                .transpose()?
                .unwrap_or(0.0),
        });
    }
    let mut ball_bars = Vec::new();
    for b in list("ball_bars")? {
        let sp = b.req("spheres")?;
        let arr = sp.arr()?;
        if arr.len() != 2 {
            return Err(sp.err(format!("a ball bar has 2 spheres, not {}", arr.len())));
        }
        let a = arr[0].str()?.to_string();
        let c = arr[1].str()?.to_string();
        for n in [&a, &c] {
            if !names.contains(n) {
                return Err(sp.err(format!("sphere {n:?} is not among `spheres`")));
            }
        }
        ball_bars.push(BallBar {
            name: b.req("name")?.str()?.to_string(),
            spheres: [a, c],
            length_mm: b.positive_f64("length_mm")?,
        });
    }
    let mut planes = Vec::new();
    for p in list("planes")? {
        planes.push(ArtefactPlane {
            name: p.req("name")?.str()?.to_string(),
            flatness_mm: p.nonneg_f64("flatness_mm")?,
        });
    }
    let u = match o.opt_obj("uncertainty_k2_mm")? {
        Some(u) => CertificateUncertainty {
            diameter: u
                .opt("diameter")
                .map(|v| v.nonneg_f64())
                .transpose()?
                .unwrap_or(0.0),
            length: u
                .opt("length")
                .map(|v| v.nonneg_f64())
                .transpose()?
                .unwrap_or(0.0),
            flatness: u
                .opt("flatness")
                .map(|v| v.nonneg_f64())
                .transpose()?
                .unwrap_or(0.0),
        },
        None => CertificateUncertainty::default(),
    };
    let m = o.obj("mpe_mm")?;
    let mpe_mm = Mpe {
        probing_form: m.positive_f64("probing_form")?,
        probing_size: m.positive_f64("probing_size")?,
        sphere_spacing: m.positive_f64("sphere_spacing")?,
        flatness: m.positive_f64("flatness")?,
    };
    Ok(Artefacts {
        spheres,
        ball_bars,
        planes,
        uncertainty_k2_mm: u,
        mpe_mm,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(text: &str) -> (tempfile_dir::Dir, std::path::PathBuf) {
        let d = tempfile_dir::Dir::new();
        let p = d.0.join("artefacts.json");
        std::fs::write(&p, text).unwrap();
        (d, p)
    }

    mod tempfile_dir {
        pub struct Dir(pub std::path::PathBuf);
        impl Dir {
            pub fn new() -> Dir {
                use std::sync::atomic::{AtomicUsize, Ordering};
                static N: AtomicUsize = AtomicUsize::new(0);
                let p = std::env::temp_dir().join(format!(
                    "stripecal-artefacts-{}-{}",
                    std::process::id(),
                    N.fetch_add(1, Ordering::Relaxed)
                ));
                std::fs::create_dir_all(&p).unwrap();
                Dir(p)
            }
        }
        impl Drop for Dir {
            fn drop(&mut self) {
                let _ = std::fs::remove_dir_all(&self.0);
            }
        }
    }

    const GOOD: &str = r#"{"format": "stripecal/artefacts@1",
 "spheres": [{"name": "A", "diameter_mm": 25.4012, "form_mm": 0.0005},
             {"name": "B", "diameter_mm": 25.3998, "form_mm": 0.0005}],
 "ball_bars": [{"name": "bar", "spheres": ["A", "B"], "length_mm": 100.0021}],
 "planes": [{"name": "plate", "flatness_mm": 0.002}],
 "uncertainty_k2_mm": {"diameter": 0.001, "length": 0.002, "flatness": 0.001},
 "mpe_mm": {"probing_form": 0.05, "probing_size": 0.03, "sphere_spacing": 0.08,
            "flatness": 0.05}}"#;

    #[test]
    fn reads_the_contract_example() {
        let (_d, p) = write(GOOD);
        let a = read_artefacts(&p).unwrap();
        assert_eq!(a.spheres.len(), 2);
        assert_eq!(a.ball_bars[0].spheres, ["A".to_string(), "B".to_string()]);
        assert_eq!(a.ball_bars[0].length_mm, 100.0021);
        assert_eq!(a.planes[0].flatness_mm, 0.002);
        assert_eq!(a.uncertainty_k2_mm.length, 0.002);
        assert_eq!(a.mpe_mm.sphere_spacing, 0.08);
    }

    #[test]
    fn mistakes_name_the_key() {
        for (bad, want) in [
            (GOOD.replace("\"B\"]", "\"C\"]"), "ball_bars[0].spheres"),
            (GOOD.replace("100.0021", "-1"), "ball_bars[0].length_mm"),
            (GOOD.replace("\"sphere_spacing\": 0.08,", ""), "mpe_mm"),
            (GOOD.replace("artefacts@1", "artefacts@2"), "format"),
        ] {
            let (_d, p) = write(&bad);
            let e = read_artefacts(&p).unwrap_err().to_string();
            assert!(e.contains(want) && e.contains("artefacts.json"), "{e}");
        }
    }
}
