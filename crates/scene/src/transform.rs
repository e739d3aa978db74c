//! Transforms given as lists of steps (`translate`, `rotate`, `scale`, `matrix`).

use glam::{Affine3A, Mat3A, Mat4, Vec3, Vec3A};

use crate::file::TransformStep;

/// Composes `steps`, applied in list order (the first step acts on the object first).
/// Returns what was expected if a step is not finite, not affine or not invertible.
pub fn compose(steps: &[TransformStep]) -> Result<Affine3A, (usize, String)> {
    let mut m = Affine3A::IDENTITY;
    for (i, step) in steps.iter().enumerate() {
        let s = match step {
            TransformStep::Translate(t) => Affine3A::from_translation(Vec3::from(*t)),
            TransformStep::Rotate { axis, angle_deg } => {
                let axis = Vec3::from(*axis);
                if !axis.is_finite() || axis.length_squared() == 0.0 || !angle_deg.is_finite() {
                    return Err((
                        i,
                        "expected a finite, non-zero rotation axis and a finite angle".into(),
                    ));
                }
                Affine3A::from_axis_angle(axis.normalize(), angle_deg.to_radians())
            }
            TransformStep::Scale(s) => Affine3A::from_scale(Vec3::from(s.expand())),
            TransformStep::Matrix(rows) => {
                let m4 = Mat4::from_cols_array(rows).transpose();
                if m4.row(3) != glam::Vec4::W {
                    return Err((
                        i,
                        "expected an affine matrix: the last row must be [0, 0, 0, 1]".into(),
                    ));
                }
                Affine3A::from_mat4(m4)
            }
        };
        m = s * m;
    }
    let det = m.matrix3.determinant();
    if !m.is_finite() || !det.is_finite() || det == 0.0 {
        return Err((
            steps.len().saturating_sub(1),
            "expected a finite, invertible transform".into(),
        ));
    }
    Ok(m)
}

/// The matrix that transforms normals: inverse transpose of the linear part.
pub fn normal_matrix(m: &Affine3A) -> Mat3A {
    m.matrix3.inverse().transpose()
}

/// If `m` is a similarity (rotation, uniform scale, translation), its scale factor.
pub fn uniform_scale(m: &Affine3A) -> Option<f32> {
    let cols = [m.matrix3.x_axis, m.matrix3.y_axis, m.matrix3.z_axis];
    let s = cols[0].length();
    let tol = 1e-4 * s;
    let orthogonal = cols[0].dot(cols[1]).abs() <= tol * s
        && cols[1].dot(cols[2]).abs() <= tol * s
        && cols[0].dot(cols[2]).abs() <= tol * s;
    let equal = cols.iter().all(|c: &Vec3A| (c.length() - s).abs() <= tol);
    (orthogonal && equal).then_some(s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::file::NumOrArray;

    #[test]
    fn steps_apply_in_list_order() {
        let steps = [
            TransformStep::Scale(NumOrArray::One(2.0)),
            TransformStep::Translate([1.0, 0.0, 0.0]),
        ];
        let m = compose(&steps).unwrap();
        // Scale first, then translate: (1,0,0) -> (2,0,0) -> (3,0,0).
        assert!((m.transform_point3(Vec3::X) - Vec3::new(3.0, 0.0, 0.0)).length() < 1e-6);
    }

    #[test]
    fn rotation_is_right_handed_in_degrees() {
        let m = compose(&[TransformStep::Rotate {
            axis: [0.0, 0.0, 1.0],
            angle_deg: 90.0,
        }])
        .unwrap();
        assert!((m.transform_vector3(Vec3::X) - Vec3::Y).length() < 1e-6);
    }

    #[test]
    fn singular_and_projective_matrices_are_rejected() {
        assert!(compose(&[TransformStep::Scale(NumOrArray::Many([1.0, 0.0, 1.0]))]).is_err());
        let mut rows = [0.0f32; 16];
        rows[0] = 1.0;
        rows[5] = 1.0;
        rows[10] = 1.0;
        rows[14] = 1.0; // row 3, column 2: projective
        assert!(
            compose(&[TransformStep::Matrix(rows)])
                .unwrap_err()
                .1
                .contains("affine")
        );
    }

    #[test]
    fn similarity_detection() {
        let sim = compose(&[
            TransformStep::Rotate {
                axis: [1.0, 2.0, 3.0],
                angle_deg: 33.0,
            },
            TransformStep::Scale(NumOrArray::One(3.0)),
        ])
        .unwrap();
        assert!((uniform_scale(&sim).unwrap() - 3.0).abs() < 1e-5);
        let squash = compose(&[TransformStep::Scale(NumOrArray::Many([1.0, 2.0, 1.0]))]).unwrap();
        assert!(uniform_scale(&squash).is_none());
    }
}
