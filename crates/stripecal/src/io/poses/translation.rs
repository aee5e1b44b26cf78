//! The translation of `T_base_hand`: `x_mm,y_mm,z_mm` or `x_m,y_m,z_m`.
//!
//! Everything inside stripecal is in millimetres: a value in metres is multiplied by
//! 1000 when read and divided by 1000 when written (ROS and Universal Robots' controllers
//! report metres, KUKA, Fanuc and Yaskawa millimetres).

/// One unit of the translation columns.
pub(super) struct Translation {
    /// The columns of x, y and z, in that order.
    pub columns: [&'static str; 3],
    /// Millimetres per unit of the columns.
    pub mm_per_unit: f64,
    /// The unit's name, for messages.
    pub unit: &'static str,
}

/// Every translation unit; a header has exactly one.
pub(super) static TRANSLATIONS: [Translation; 2] = [
    Translation {
        columns: ["x_mm", "y_mm", "z_mm"],
        mm_per_unit: 1.0,
        unit: "millimetres",
    },
    Translation {
        columns: ["x_m", "y_m", "z_m"],
        mm_per_unit: 1000.0,
        unit: "metres",
    },
];
