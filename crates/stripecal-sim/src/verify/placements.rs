//! The artefacts' positions in the working volume (the frame: [`super`]'s docs).

/// Where a ball bar stands (see the module docs for the frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BarPlacement {
    /// Turn of the camera (and the bar) about the table's normal from the home
    /// orientation, deg.
    pub yaw_deg: f64,
    /// The bar's angle out of the plane perpendicular to the optical axis (positive:
    /// sphere B farther), deg.
    pub tilt_deg: f64,
    /// The bar's angle from the sweep towards the stripe (diagonal in the image), deg.
    pub skew_deg: f64,
    /// The bar's middle from the reference point, base frame, mm.
    pub offset_mm: [f64; 3],
    /// Depth of the bar's middle (the centres' mean) along the optical axis, mm.
    pub depth_mm: f64,
}

/// Where the plate stands (see the module docs for the frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlatePlacement {
    pub yaw_deg: f64,
    /// Turn of the plate about the stripe's direction `w` (depth changes along the
    /// sweep), deg.
    pub tilt_w_deg: f64,
    /// Turn of the plate about the sweep `s` (depth changes along the stripe), deg.
    pub tilt_s_deg: f64,
    pub offset_mm: [f64; 3],
    /// Depth of the plate's centre along the optical axis, mm.
    pub depth_mm: f64,
}

/// The ball bar's positions: along the sweep, across it (turned 90 deg), the two
/// diagonals, tilted in depth both ways, and diagonal in the image at a far stand-off;
/// the bar's middle moved +-40 mm across and +-20 mm up and down the working volume,
/// stand-offs 98..118 mm.
pub const BAR_PLACEMENTS: [BarPlacement; 7] = [
    BarPlacement {
        yaw_deg: 0.0,
        tilt_deg: 0.0,
        skew_deg: 0.0,
        offset_mm: [0.0, 0.0, 0.0],
        depth_mm: 105.0,
    },
    BarPlacement {
        yaw_deg: 90.0,
        tilt_deg: 0.0,
        skew_deg: 0.0,
        offset_mm: [0.0, 40.0, 0.0],
        depth_mm: 105.0,
    },
    BarPlacement {
        yaw_deg: 45.0,
        tilt_deg: 0.0,
        skew_deg: 0.0,
        offset_mm: [40.0, 0.0, 10.0],
        depth_mm: 98.0,
    },
    BarPlacement {
        yaw_deg: -45.0,
        tilt_deg: 0.0,
        skew_deg: 0.0,
        offset_mm: [-40.0, 0.0, -10.0],
        depth_mm: 118.0,
    },
    BarPlacement {
        yaw_deg: 0.0,
        tilt_deg: 12.0,
        skew_deg: 0.0,
        offset_mm: [0.0, -40.0, 20.0],
        depth_mm: 108.0,
    },
    BarPlacement {
        yaw_deg: 90.0,
        tilt_deg: -12.0,
        skew_deg: 0.0,
        offset_mm: [-30.0, -30.0, -20.0],
        depth_mm: 108.0,
    },
    BarPlacement {
        yaw_deg: 135.0,
        tilt_deg: 0.0,
        skew_deg: 5.0,
        offset_mm: [30.0, 30.0, -20.0],
        depth_mm: 115.0,
    },
];

/// The plate's positions: facing the sensor, tilted 25 deg about the stripe's
/// direction, tilted 25 deg about the sweep (turned 90 deg).
pub const PLATE_PLACEMENTS: [PlatePlacement; 3] = [
    PlatePlacement {
        yaw_deg: 0.0,
        tilt_w_deg: 0.0,
        tilt_s_deg: 0.0,
        offset_mm: [0.0, 0.0, 0.0],
        depth_mm: 105.0,
    },
    PlatePlacement {
        yaw_deg: 45.0,
        tilt_w_deg: 25.0,
        tilt_s_deg: 0.0,
        offset_mm: [30.0, -30.0, 10.0],
        depth_mm: 108.0,
    },
    PlatePlacement {
        yaw_deg: 90.0,
        tilt_w_deg: 0.0,
        tilt_s_deg: -25.0,
        offset_mm: [-30.0, 30.0, -10.0],
        depth_mm: 108.0,
    },
];
