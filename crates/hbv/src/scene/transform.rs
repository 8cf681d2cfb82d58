//! `InstanceTransform`: an instance's placement, an affine map in f64, checked once.

use glam::{DAffine3, DMat3, DMat4, DVec3};

use super::SceneError;

/// Where an instance sits: the affine map `world = A · local + b` in f64, with its inverse and
/// its cofactor matrix computed once, when it is checked.
///
/// The checks ([`InstanceTransform::new`]): every entry finite, and the linear part `A`
/// invertible with room to spare,
///
/// ```text
///   |det A| ≥ 2^-40 · s³,   s = max |a_ij|,
/// ```
///
/// and an inverse whose entries are finite. `det A / s³` is scale-free (it is the determinant of
/// `A / s`, whose entries are at most 1 in magnitude), and it is at least about `1/κ²` for the
/// condition number `κ` of `A`, so the rule refuses maps that squash some direction by more than
/// about a million times relative to the others (`diag(1e-6, 1e-6, 1)` is still accepted):
/// rays carried into such an instance's space in f32 would lose most of their digits there.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)] // `inverse` first: with an instance's hot fields, what a ray's visit reads.
pub struct InstanceTransform {
    inverse: DAffine3,
    affine: DAffine3,
    /// `cof(A) = det(A) · A^-T`: maps a local `(p1 - p0) × (p2 - p0)` to the world one,
    /// `cross(A e1, A e2) = cof(A) (e1 × e2)`, so a mirroring `A` flips normals.
    cofactor: DMat3,
    /// `κ∞(A) = ‖A‖∞ ‖A^-1‖∞` (largest row sums of magnitudes): how much the rounding of a ray
    /// carried into the instance's space grows when it is mapped back.
    conditioning: f64,
}

/// `|det A| ≥ SINGULAR_RATIO · s³` is required (see [`InstanceTransform`]).
const SINGULAR_RATIO: f64 = 1.0 / (1u64 << 40) as f64;

impl InstanceTransform {
    /// The identity: the mesh placed as it is.
    pub const IDENTITY: InstanceTransform = InstanceTransform {
        affine: DAffine3::IDENTITY,
        inverse: DAffine3::IDENTITY,
        cofactor: DMat3::IDENTITY,
        conditioning: 1.0,
    };

    /// Checks `affine` (see [`InstanceTransform`] for the rule). Entries are reported as rows and
    /// columns of the 3×4 matrix `[A | b]`.
    pub fn new(affine: DAffine3) -> Result<Self, SceneError> {
        let rows = Self::rows_of(&affine);
        for (row, values) in rows.iter().enumerate() {
            for (column, &value) in values.iter().enumerate() {
                if !value.is_finite() {
                    return Err(SceneError::NonFiniteTransform { row, column, value });
                }
            }
        }
        let a = affine.matrix3;
        let largest_entry = a.abs().to_cols_array().into_iter().fold(0.0, f64::max);
        let determinant = a.determinant();
        let singular = SceneError::SingularTransform {
            determinant,
            largest_entry,
        };
        // `s³` underflows for tiny `s`: compare `det (A / s)` instead, which is scale-free.
        if largest_entry == 0.0 || (a / largest_entry).determinant().abs() < SINGULAR_RATIO {
            return Err(singular);
        }
        let inverse = affine.inverse();
        if !inverse.is_finite() {
            return Err(singular);
        }
        let cofactor = DMat3::from_cols(
            a.y_axis.cross(a.z_axis),
            a.z_axis.cross(a.x_axis),
            a.x_axis.cross(a.y_axis),
        );
        if !cofactor.is_finite() {
            return Err(singular);
        }
        let row_sum_norm = |m: DMat3| {
            let m = m.transpose().abs();
            (m.x_axis + m.y_axis + m.z_axis).max_element()
        };
        Ok(Self {
            affine,
            inverse,
            cofactor,
            conditioning: row_sum_norm(a) * row_sum_norm(inverse.matrix3),
        })
    }

    /// The map given as the three rows of `[A | b]` (row-major, as NumPy holds a 3×4 array).
    pub fn from_rows(rows: [[f64; 4]; 3]) -> Result<Self, SceneError> {
        let column = |j: usize| DVec3::new(rows[0][j], rows[1][j], rows[2][j]);
        Self::new(DAffine3::from_cols(
            column(0),
            column(1),
            column(2),
            column(3),
        ))
    }

    /// The map given as a 4×4 matrix acting on column vectors `(x, y, z, 1)`; its bottom row must
    /// be `0 0 0 1`.
    pub fn from_mat4(matrix: DMat4) -> Result<Self, SceneError> {
        let bottom_row = matrix.row(3).to_array();
        for (column, &value) in bottom_row.iter().enumerate() {
            if !value.is_finite() {
                return Err(SceneError::NonFiniteTransform {
                    row: 3,
                    column,
                    value,
                });
            }
        }
        if bottom_row != [0.0, 0.0, 0.0, 1.0] {
            return Err(SceneError::NotAffine { bottom_row });
        }
        let row = |i: usize| matrix.row(i).to_array();
        Self::from_rows([row(0), row(1), row(2)])
    }

    /// A translation by `offset`.
    pub fn from_translation(offset: DVec3) -> Result<Self, SceneError> {
        Self::new(DAffine3::from_translation(offset))
    }

    /// The map `local → world`.
    pub fn affine(&self) -> DAffine3 {
        self.affine
    }

    /// The map `world → local`.
    pub fn inverse(&self) -> DAffine3 {
        self.inverse
    }

    /// `κ∞(A) = ‖A‖∞ ‖A^-1‖∞` of the linear part: 1 for a uniform scale (and axis
    /// permutations, mirrors), at most 3 for any rotation, at most `3 s_max / s_min` for a
    /// rotation and scales `s`. The factor by which the f32 rounding of a ray carried into the
    /// instance's space grows in world space.
    pub fn conditioning(&self) -> f64 {
        self.conditioning
    }

    /// The world-space scaled normal `cross(A e1, A e2)` of a triangle whose local one is
    /// `local = e1 × e2`.
    pub(crate) fn world_scaled_normal(&self, local: DVec3) -> DVec3 {
        self.cofactor * local
    }

    /// The rows of `[A | b]`.
    fn rows_of(affine: &DAffine3) -> [[f64; 4]; 3] {
        let a = affine.matrix3;
        let b = affine.translation;
        std::array::from_fn(|i| {
            let r = a.row(i);
            [r.x, r.y, r.z, b[i]]
        })
    }
}

impl Default for InstanceTransform {
    fn default() -> Self {
        Self::IDENTITY
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cofactor_maps_cross_products() {
        let t = InstanceTransform::from_rows([
            [0.0, -2.0, 0.0, 1.0],
            [1.0, 0.0, 0.5, 2.0],
            [0.0, 0.0, -3.0, 3.0],
        ])
        .unwrap();
        let a = t.affine().matrix3;
        let (e1, e2) = (DVec3::new(1.0, 2.0, -1.0), DVec3::new(0.5, -1.0, 4.0));
        let direct = (a * e1).cross(a * e2);
        assert!((t.world_scaled_normal(e1.cross(e2)) - direct).length() < 1e-12);
        let round_trip = t
            .inverse()
            .transform_point3(t.affine().transform_point3(e1));
        assert!((round_trip - e1).length() < 1e-12);
    }

    #[test]
    fn refusals_name_the_entry() {
        let mut rows = [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
        ];
        rows[1][3] = f64::NAN;
        let e = InstanceTransform::from_rows(rows).unwrap_err();
        assert!(matches!(
            e,
            SceneError::NonFiniteTransform {
                row: 1,
                column: 3,
                ..
            }
        ));
        assert!(e.to_string().contains("row 1, column 3"));
        let flat = DAffine3::from_scale(DVec3::new(1.0, 1.0, 0.0));
        assert!(matches!(
            InstanceTransform::new(flat),
            Err(SceneError::SingularTransform { .. })
        ));
        let mut projective = DMat4::IDENTITY;
        projective.x_axis.w = 0.5;
        assert!(matches!(
            InstanceTransform::from_mat4(projective),
            Err(SceneError::NotAffine { .. })
        ));
        // Tiny but well-conditioned maps are fine; squashing by a million is the limit.
        assert!(InstanceTransform::new(DAffine3::from_scale(DVec3::splat(1e-100))).is_ok());
        assert!(InstanceTransform::new(DAffine3::from_scale(DVec3::new(1e-6, 1e-6, 1.0))).is_ok());
        assert!(InstanceTransform::new(DAffine3::from_scale(DVec3::new(1e-7, 1e-7, 1.0))).is_err());
    }
}
