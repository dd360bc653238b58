//! Probability densities tagged with their measure, so that an area density is never used
//! where a solid-angle one is expected (the most common bug in light transport code).

/// Density per unit solid angle (steradian).
#[derive(Clone, Copy, Debug, Default, PartialEq, PartialOrd)]
pub struct SolidAnglePdf(pub f32);

/// Density per unit surface area.
#[derive(Clone, Copy, Debug, Default, PartialEq, PartialOrd)]
pub struct AreaPdf(pub f32);

impl AreaPdf {
    /// Converts to solid angle seen from a point at squared distance `dist2`, where the
    /// surface's normal makes cosine `cos_surface` with the connecting direction:
    /// `p_ω = p_A · d² / |cos θ|`. Infinite for grazing directions.
    #[inline]
    #[must_use]
    pub fn to_solid_angle(self, dist2: f32, cos_surface: f32) -> SolidAnglePdf {
        SolidAnglePdf(self.0 * dist2 / cos_surface.abs())
    }
}

impl SolidAnglePdf {
    /// Converts to area measure at a surface at squared distance `dist2` with cosine
    /// `cos_surface`: `p_A = p_ω · |cos θ| / d²`.
    #[inline]
    #[must_use]
    pub fn to_area(self, dist2: f32, cos_surface: f32) -> AreaPdf {
        AreaPdf(self.0 * cos_surface.abs() / dist2)
    }
}
