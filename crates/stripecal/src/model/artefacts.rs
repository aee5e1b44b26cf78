//! Verification artefacts (`artefacts.json`, spec/DATASET.md): the certified reference
//! values of the artefacts an acceptance test measures and the maximum permissible
//! errors (MPE) the user accepts.

/// A certified sphere.
#[derive(Debug, Clone, PartialEq)]
pub struct ArtefactSphere {
    pub name: String,
    pub diameter_mm: f64,
    /// Its form deviation (certificate), mm.
    pub form_mm: f64,
}

/// A ball bar: two named spheres and the certified distance of their centres.
#[derive(Debug, Clone, PartialEq)]
pub struct BallBar {
    pub name: String,
    pub spheres: [String; 2],
    pub length_mm: f64,
}

/// A certified flat (plate).
#[derive(Debug, Clone, PartialEq)]
pub struct ArtefactPlane {
    pub name: String,
    pub flatness_mm: f64,
}

/// The certificates' expanded uncertainties (k = 2), mm.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CertificateUncertainty {
    pub diameter: f64,
    pub length: f64,
    pub flatness: f64,
}

/// Maximum permissible errors of the four characteristics, mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mpe {
    pub probing_form: f64,
    pub probing_size: f64,
    pub sphere_spacing: f64,
    pub flatness: f64,
}

/// The contents of `artefacts.json`.
#[derive(Debug, Clone, PartialEq)]
pub struct Artefacts {
    pub spheres: Vec<ArtefactSphere>,
    pub ball_bars: Vec<BallBar>,
    pub planes: Vec<ArtefactPlane>,
    pub uncertainty_k2_mm: CertificateUncertainty,
    pub mpe_mm: Mpe,
}

impl Artefacts {
    /// The sphere named `name`.
    pub fn sphere(&self, name: &str) -> Option<&ArtefactSphere> {
        self.spheres.iter().find(|s| s.name == name)
    }
}
