//! Sharp booleans of two point-set solids (Guo & Qin §5.1, Table 1).
//!
//! With `s₁`, `s₂` the operands' fields (eq. 5; positive inside), the result keeps two
//! patches `Q₁ ⊆ P₁` and `Q₂ ⊆ P₂`:
//!
//! | operation | `Q₁` | `Q₂` |
//! | --- | --- | --- |
//! | `S₁ ∪ S₂` | `{p ∈ P₁ : s₂(p) < 0}` | `{p ∈ P₂ : s₁(p) < 0}` |
//! | `S₁ ∩ S₂` | `{p ∈ P₁ : s₂(p) ≥ 0}` | `{p ∈ P₂ : s₁(p) ≥ 0}` |
//! | `S₁ − S₂` | `{p ∈ P₁ : s₂(p) < 0}` | `{p ∈ P₂ : s₁(p) ≥ 0}` |
//!
//! Each patch keeps its points' local fields, so each is a point-set surface of its own; the
//! result's field is `max(a, b)` for a union and `min(a, b)` otherwise, where `b` is patch 2's
//! field, negated (with its normals flipped) for a difference. The two patches are never
//! blended into one field, so the intersection curve stays a crease: where it is meshed, each
//! side's normals are its own patch's gradient (the paper renders it by sampling near each
//! point and discarding samples outside the other patch; the mesher's `min`/`max` does the
//! same on a grid).

use glam::Vec3;

use super::error::PointSetError;
use super::surface::PointSet;
use dynaclay_core::field::ImplicitField;
use dynaclay_core::mesh::ScalarField;

/// A boolean operation of Table 1.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BooleanOp {
    Union,
    Intersection,
    Difference,
}

/// The result of a sharp boolean: two patches and how their fields combine.
#[derive(Clone, Debug)]
pub struct SharpBoolean {
    /// `Q₁`, with `P₁`'s local fields.
    pub first: PointSet,
    /// `Q₂`, with `P₂`'s local fields (negated, normals flipped, for a difference).
    pub second: PointSet,
    /// The operation.
    pub op: BooleanOp,
}

/// The points of `set` kept by `keep`, with their normals, colours and fields; `flip` negates
/// the fields and normals.
fn subset(set: &PointSet, keep: &[bool], flip: bool) -> Result<PointSet, PointSetError> {
    let sign = if flip { -1.0 } else { 1.0 };
    let mut points = Vec::new();
    let mut normals = Vec::new();
    let mut colours = Vec::new();
    let mut fields = Vec::new();
    for (i, _) in keep.iter().enumerate().filter(|(_, k)| **k) {
        points.push(set.points[i]);
        normals.push(set.normals[i] * sign);
        colours.push(set.colours[i]);
        let mut f = set.fields[i];
        for c in &mut f.coeffs {
            *c *= sign;
        }
        fields.push(f);
    }
    PointSet::from_parts(points, normals, colours, fields, set.spacing_fu)
}

impl SharpBoolean {
    /// Classifies the points of `a` and `b` by Table 1 and keeps the two patches.
    ///
    /// # Errors
    /// When a patch's index cannot be built.
    pub fn new(a: &PointSet, b: &PointSet, op: BooleanOp) -> Result<Self, PointSetError> {
        let outside_b: Vec<bool> = a.points.iter().map(|&p| b.blend(p).0 < 0.0).collect();
        let outside_a: Vec<bool> = b.points.iter().map(|&p| a.blend(p).0 < 0.0).collect();
        let (keep1, keep2): (Vec<bool>, Vec<bool>) = match op {
            BooleanOp::Union => (outside_b, outside_a),
            BooleanOp::Intersection => (
                outside_b.iter().map(|o| !o).collect(),
                outside_a.iter().map(|o| !o).collect(),
            ),
            BooleanOp::Difference => (outside_b, outside_a.iter().map(|o| !o).collect()),
        };
        Ok(Self {
            first: subset(a, &keep1, false)?,
            second: subset(b, &keep2, op == BooleanOp::Difference)?,
            op,
        })
    }

    /// All points of both patches, with their normals and colours.
    #[must_use]
    pub fn points(&self) -> (Vec<Vec3>, Vec<Vec3>, Vec<[u8; 3]>) {
        let mut p = self.first.points.clone();
        p.extend_from_slice(&self.second.points);
        let mut n = self.first.normals.clone();
        n.extend_from_slice(&self.second.normals);
        let mut c = self.first.colours.clone();
        c.extend_from_slice(&self.second.colours);
        (p, n, c)
    }

    /// Value and gradient of the combined field; the gradient is the chosen patch's.
    #[must_use]
    pub fn combined(&self, x: Vec3) -> (f32, Vec3) {
        let a = self.first.blend(x);
        let b = self.second.blend(x);
        let take_a = match self.op {
            BooleanOp::Union => a.0 >= b.0,
            BooleanOp::Intersection | BooleanOp::Difference => a.0 <= b.0,
        };
        if take_a { a } else { b }
    }
}

impl ImplicitField for SharpBoolean {
    fn iso(&self) -> f32 {
        0.0
    }

    fn value(&self, p: Vec3) -> f32 {
        self.combined(p).0
    }

    fn value_and_gradient(&self, p: Vec3) -> (f32, Vec3) {
        self.combined(p)
    }
}

/// Meshed by per-sample queries (the trait's default block sampling).
impl ScalarField for SharpBoolean {}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::PointCloud;
    use crate::pointset::PointSetOptions;
    use crate::pointset::surface::tests::sphere_cloud;
    use dynaclay_core::mesh::{BrickOctree, SampleGrid};

    /// The faces of the cube `± half`, sampled on a grid of `n × n` per face, with normals.
    fn cube_cloud(half: f32, n: usize) -> PointCloud {
        let mut points = Vec::new();
        let mut normals = Vec::new();
        for axis in 0..3 {
            for sign in [-1.0f32, 1.0] {
                for i in 0..n {
                    for j in 0..n {
                        let u = -half + 2.0 * half * (i as f32 + 0.5) / n as f32;
                        let v = -half + 2.0 * half * (j as f32 + 0.5) / n as f32;
                        let mut p = [0.0; 3];
                        p[axis] = sign * half;
                        p[(axis + 1) % 3] = u;
                        p[(axis + 2) % 3] = v;
                        let mut nn = [0.0; 3];
                        nn[axis] = sign;
                        points.push(Vec3::from(p));
                        normals.push(Vec3::from(nn));
                    }
                }
            }
        }
        PointCloud {
            points,
            normals: Some(normals),
        }
    }

    fn cube_and_sphere() -> (PointSet, PointSet, Vec3, f32) {
        let opts = PointSetOptions::default();
        let (cube, _) = PointSet::build(&cube_cloud(0.5, 25), &opts).unwrap();
        let centre = Vec3::new(0.0, 0.0, 0.5);
        let radius = 0.3;
        let (sphere, _) = PointSet::build(&sphere_cloud(centre, radius, 700), &opts).unwrap();
        (cube, sphere, centre, radius)
    }

    #[test]
    fn table_1_classification() {
        let (cube, sphere, centre, radius) = cube_and_sphere();
        let diff = SharpBoolean::new(&cube, &sphere, BooleanOp::Difference).unwrap();
        // Q1: the cube's points outside the sphere; Q2: the sphere's points inside the cube.
        assert!(
            diff.first
                .points
                .iter()
                .all(|p| (*p - centre).length() > radius - 0.02)
        );
        assert!(diff.first.len() < cube.len());
        assert!(diff.second.points.iter().all(|p| p.z < 0.5 + 0.02));
        // The kept sphere points face into the cavity.
        for (p, n) in diff.second.points.iter().zip(&diff.second.normals) {
            assert!(n.dot(centre - *p) > 0.0);
        }
        let union = SharpBoolean::new(&cube, &sphere, BooleanOp::Union).unwrap();
        assert!(union.second.points.iter().all(|p| p.z > 0.5 - 0.02));
        let inter = SharpBoolean::new(&cube, &sphere, BooleanOp::Intersection).unwrap();
        assert!(
            inter
                .first
                .points
                .iter()
                .all(|p| (*p - centre).length() < radius + 0.02)
        );
        assert_eq!(inter.second.len() + union.second.len(), sphere.len());
        // Inside/outside of the results.
        assert!(diff.value(Vec3::new(0.0, 0.0, 0.4)) < 0.0);
        assert!(diff.value(Vec3::new(0.0, 0.0, 0.0)) > 0.0);
        assert!(union.value(Vec3::new(0.0, 0.0, 0.7)) > 0.0);
        assert!(inter.value(Vec3::new(0.0, 0.0, 0.0)) < 0.0);
    }

    #[test]
    fn cube_minus_sphere_meshes_with_a_crease_not_a_fillet() {
        let (cube, sphere, centre, radius) = cube_and_sphere();
        let diff = SharpBoolean::new(&cube, &sphere, BooleanOp::Difference).unwrap();
        let cell = 0.02;
        let grid = SampleGrid::new(Vec3::splat(-0.64), cell, [64, 64, 64]).unwrap();
        let mesh = BrickOctree::build(grid, &diff).weld();
        assert!(mesh.triangle_count() > 1000);
        // Vertices 1.5 to 4 cells from the crease circle (z = 0.5, ρ = radius), on each side.
        let (mut face_n, mut sphere_n, mut tilt) = (Vec3::ZERO, 0usize, 0.0f32);
        let (mut face_count, mut worst_face, mut worst_sphere) = (0usize, 0.0f32, 0.0f32);
        let mut sphere_sum = 0.0f32;
        for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
            let rho = (p.x * p.x + p.y * p.y).sqrt();
            if (p.z - 0.5).abs() < 0.5 * cell
                && rho > radius + 1.5 * cell
                && rho < radius + 4.0 * cell
            {
                face_n += *n;
                face_count += 1;
                worst_face = worst_face.max(n.angle_between(Vec3::Z).to_degrees());
            }
            let below = 0.5 - p.z;
            if ((*p - centre).length() - radius).abs() < 0.5 * cell
                && below > 1.5 * cell
                && below < 4.0 * cell
            {
                let truth = (centre - *p).normalize();
                worst_sphere = worst_sphere.max(n.angle_between(truth).to_degrees());
                // The true normal there tilts up from the horizontal by asin(below / radius).
                tilt += (below / radius).asin().to_degrees();
                sphere_sum += n.angle_between(Vec3::Z).to_degrees();
                sphere_n += 1;
            }
        }
        assert!(
            face_count > 20 && sphere_n > 20,
            "{face_count} face, {sphere_n} sphere"
        );
        assert!(worst_face < 12.0, "face normals off by {worst_face}°");
        assert!(worst_sphere < 12.0, "sphere normals off by {worst_sphere}°");
        // The dihedral angle across the crease: 90° for a sphere centred on the face. Measured
        // as the sphere side's angle to the face normal, corrected for the tilt of the band.
        let dihedral = (sphere_sum + tilt) / sphere_n as f32;
        let face_dir = face_n.normalize().angle_between(Vec3::Z).to_degrees();
        assert!(face_dir < 3.0, "face side {face_dir}°");
        assert!((dihedral - 90.0).abs() < 6.0, "dihedral {dihedral}°");
    }
}
