//! Particles on the clay drawn as small discs: an instance buffer of [`ParticleDisc`]s drawn
//! as one quad each by `shaders/particles.wgsl`, which orients each quad by the particle's
//! normal and cuts it to a disc.

use glam::Vec3;

/// The discs' colour (linear RGB; the shader's `DISC_COLOR`), a green that neither the clay
/// nor the overlays use.
pub const PARTICLE_DISC_COLOR: [f32; 3] = [0.02, 0.60, 0.08];

/// Disc radius as a fraction of the particle's radius: particles sit about one radius apart,
/// so half-radius discs show each one without covering the clay.
pub const DISC_SCALE: f32 = 0.5;

/// How far a disc sits off the surface along its normal, as a fraction of its radius (the
/// shader's `LIFT`), so the clay does not hide it.
pub const DISC_LIFT: f32 = 0.25;

/// One disc: centre, unit normal and radius in world units (the instance layout of
/// `shaders/particles.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct ParticleDisc {
    pub centre: [f32; 3],
    pub normal: [f32; 3],
    pub radius: f32,
}

pub(crate) const DISC_ATTRIBUTES: [wgpu::VertexAttribute; 3] =
    wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32];

/// Fills `out` with one disc per particle (radius [`DISC_SCALE`] times the particle's),
/// skipping particles with a non-finite position or radius; the three slices are read up to
/// the shortest.
pub fn particle_discs(
    out: &mut Vec<ParticleDisc>,
    positions: &[Vec3],
    normals: &[Vec3],
    radii: &[f32],
) {
    out.clear();
    out.extend(
        positions
            .iter()
            .zip(normals)
            .zip(radii)
            .filter(|((p, n), r)| p.is_finite() && n.is_finite() && r.is_finite() && **r > 0.0)
            .map(|((p, n), r)| ParticleDisc {
                centre: p.to_array(),
                normal: n.to_array(),
                radius: r * DISC_SCALE,
            }),
    );
}

/// A growable GPU instance buffer of discs.
#[derive(Default)]
pub(crate) struct DiscBuffer {
    pub(crate) buffer: Option<wgpu::Buffer>,
    pub(crate) count: u32,
}

impl DiscBuffer {
    /// Uploads `discs` (grows the buffer to twice the need when it does not fit).
    pub(crate) fn write(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        discs: &[ParticleDisc],
    ) {
        self.count = u32::try_from(discs.len()).unwrap_or(0);
        if discs.is_empty() {
            return;
        }
        let bytes: &[u8] = bytemuck::cast_slice(discs);
        let fits = self
            .buffer
            .as_ref()
            .is_some_and(|b| b.size() >= bytes.len() as u64);
        if !fits {
            self.buffer = Some(device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("particle discs"),
                size: (bytes.len() as u64 * 2).next_multiple_of(4),
                usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }));
        }
        if let Some(b) = &self.buffer {
            queue.write_buffer(b, 0, bytes);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn discs_take_half_the_radius_and_skip_bad_particles() {
        let mut out = vec![ParticleDisc {
            centre: [9.0; 3],
            normal: [0.0; 3],
            radius: 1.0,
        }];
        particle_discs(
            &mut out,
            &[Vec3::X, Vec3::splat(f32::NAN), Vec3::Y],
            &[Vec3::Z, Vec3::Z, Vec3::Z],
            &[0.2, 0.2, 0.4],
        );
        assert_eq!(out.len(), 2);
        assert_eq!(out[0].centre, [1.0, 0.0, 0.0]);
        assert!((out[1].radius - 0.4 * DISC_SCALE).abs() < 1e-7);
    }
}
