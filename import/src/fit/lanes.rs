//! Sums over a point's neighbourhood in [`LANES`] lanes: the points of each row of cells a
//! radius search passes over ([`super::consensus::PointGrid::for_each_row_near`]) are read
//! [`LANES`] at a time from columns laid out in the grid's order, each weighed (those beyond
//! reach add nothing), and the terms added lane by lane; the lanes are added together at the
//! end, in lane order.
//!
//! Where the CPU has AVX2 a second build of the same code runs ([`add_row`]): a block is then
//! one 256-bit register instead of two SSE2 ones. Every lane runs the same operations in the
//! same order (no fused multiply-add: Rust never contracts a multiply and an add), so both
//! builds give the same sums bit for bit, on any number of threads.
//!
//! NOTE: a term per point within reach, picked by the search without a branch and then added
//! in turn, is a Gaussian and a dozen products at a time: at the bandwidths a noisy cloud
//! needs (about 120 neighbours within reach) the moving planes, the normals' smoothing and the
//! curvature were about half of an import's CPU (bench/RESULTS.md, "Import time: the
//! neighbourhoods in lanes"). In lanes every point of the rows is weighed (about three times
//! those within reach), eight at a time.

use std::ops::Range;

/// Points weighed together: eight, one AVX2 register (two SSE2 registers on the baseline).
pub(crate) const LANES: usize = 8;

/// One value per lane.
pub(crate) type Lanes = [f32; LANES];

/// The values of `column` in slots `start..start + LANES` (the caller's columns are padded by
/// [`LANES`] slots, so a block that starts in a row never reads past them).
#[inline(always)]
pub(crate) fn lanes_of(column: &[f32], start: usize) -> Lanes {
    let mut lanes = [0.0; LANES];
    lanes.copy_from_slice(&column[start..start + LANES]);
    lanes
}

/// The lanes of three columns from `start` (a point's coordinates, a normal's components).
#[inline(always)]
pub(crate) fn lanes_of_three(columns: [&[f32]; 3], start: usize) -> [Lanes; 3] {
    columns.map(|column| lanes_of(column, start))
}

/// The lanes added together, in lane order.
#[inline(always)]
pub(crate) fn total(lanes: &Lanes) -> f32 {
    lanes.iter().fold(0.0, |sum, &v| sum + v)
}

/// `value` where `keep`, 0 elsewhere, as `value` times 1 or 0 (no branch). `value` must be
/// finite (an infinite or NaN one times 0 is NaN). Added to a sum, it adds `value` or leaves
/// the sum as it was (but for the sign of a zero sum).
///
/// NOTE: as a blend (`if keep { value } else { 0.0 }`), a sum of it was compiled into a
/// masked store of the sum's lanes (`vmaskmovps`), which AMD's cores run as a long
/// microcode sequence: the normals' vote over a 1% noise cloud took 134 ms, 32 ms as the
/// product, the same meshes byte for byte (bench/RESULTS.md, "The lanes' sums without
/// masked stores").
#[inline(always)]
pub(crate) fn kept(keep: bool, value: f32) -> f32 {
    value * f32::from(u8::from(keep))
}

/// A neighbourhood's sums, block by block.
pub(crate) trait LaneSums {
    /// Adds the terms of the points in slots `start..start + LANES`, the first `valid` of
    /// them (the rest belong to another row, or are the columns' padding).
    fn add_block(&mut self, start: usize, valid: usize);
}

/// Whether this CPU runs the AVX2 build of [`add_row`].
#[must_use]
pub(crate) fn has_wide_lanes() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Proof that this CPU runs the AVX2 build of [`add_row`]: only [`WideLanes::detect`] makes
/// one, after asking the CPU.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct WideLanes(());

impl WideLanes {
    /// `Some` where this CPU has AVX2.
    #[must_use]
    pub(crate) fn detect() -> Option<Self> {
        has_wide_lanes().then_some(Self(()))
    }
}

/// Adds the terms of the points in `slots` (a row of a search) to `sums`, with the AVX2 build
/// where `wide` is given (the same sums bit for bit).
#[inline]
pub(crate) fn add_row<S: LaneSums>(sums: &mut S, slots: Range<usize>, wide: Option<WideLanes>) {
    #[cfg(target_arch = "x86_64")]
    if wide.is_some() {
        // SAFETY: a `WideLanes` exists only where the CPU has AVX2 (`WideLanes::detect`).
        unsafe { add_row_avx2(sums, slots) };
        return;
    }
    let _ = wide;
    add_row_in_lanes(sums, slots);
}

/// [`add_row`] built for AVX2.
///
/// # Safety
/// The CPU must have AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn add_row_avx2<S: LaneSums>(sums: &mut S, slots: Range<usize>) {
    add_row_in_lanes(sums, slots);
}

/// [`add_row`]'s loop (inlined into each build, with the sums' [`LaneSums::add_block`]).
#[inline(always)]
fn add_row_in_lanes<S: LaneSums>(sums: &mut S, slots: Range<usize>) {
    for start in slots.clone().step_by(LANES) {
        sums.add_block(start, slots.end - start);
    }
}

/// `exp(−t)` as [`super::consensus::exp_neg`] gives it, without its branches, for `t` up to 80
/// (a point within a few bandwidths): the same value bit for bit there. Beyond, and for a
/// NaN, `t` is taken into `[0, 80]` first (a finite value the caller leaves out).
#[inline(always)]
#[allow(clippy::manual_clamp)] // `clamp` keeps a NaN, which the truncation below must not see.
pub(crate) fn exp_neg_lane(t: f32) -> f32 {
    // `max` takes a NaN to 0.
    let z = t.max(0.0).min(80.0) * std::f32::consts::LOG2_E;
    // SAFETY: `z + 0.5` is in [0.5, 116], where the truncation is defined (the saturating
    // `as i32` is the same there, but its checks keep it out of vector registers).
    let k: i32 = unsafe { (z + 0.5).to_int_unchecked() };
    super::consensus::two_to_minus(z, k)
}

#[cfg(test)]
mod tests {
    use super::super::consensus::exp_neg;
    use super::*;

    #[test]
    fn the_branch_free_gaussian_is_exp_neg_bit_for_bit_up_to_80() {
        for step in 0..=400_000 {
            let t = 80.0 * step as f32 / 400_000.0;
            assert_eq!(exp_neg_lane(t).to_bits(), exp_neg(t).to_bits(), "at {t}");
        }
        // Beyond, at infinity and for a NaN, a finite value (left out by the caller).
        for t in [81.0, 1e3, 1e30, f32::INFINITY, f32::NAN, -1.0] {
            let e = exp_neg_lane(t);
            assert!(e.is_finite() && (0.0..=1.0).contains(&e), "{t}: {e}");
        }
    }

    /// Sums of `value[s] · factor` over the valid slots, for the two builds.
    struct Scaled<'a> {
        value: &'a [f32],
        factor: f32,
        sums: Lanes,
    }

    impl LaneSums for Scaled<'_> {
        fn add_block(&mut self, start: usize, valid: usize) {
            let value = lanes_of(self.value, start);
            for (l, (sum, value)) in self.sums.iter_mut().zip(value).enumerate() {
                *sum += kept(l < valid, value * self.factor);
            }
        }
    }

    #[test]
    fn a_row_adds_each_of_its_slots_once_in_its_lane_on_both_builds() {
        let value: Vec<f32> = (0..40 + LANES).map(|s| 1.0 / (1.0 + s as f32)).collect();
        for slots in [0..0, 3..4, 5..13, 2..37, 0..40] {
            let mut expected = [0.0f32; LANES];
            for s in slots.clone() {
                expected[(s - slots.start) % LANES] += value[s] * 3.0;
            }
            for wide in [None, WideLanes::detect()] {
                let mut scaled = Scaled {
                    value: &value,
                    factor: 3.0,
                    sums: [0.0; LANES],
                };
                add_row(&mut scaled, slots.clone(), wide);
                assert_eq!(
                    scaled.sums.map(f32::to_bits),
                    expected.map(f32::to_bits),
                    "{slots:?}, wide: {wide:?}"
                );
                assert_eq!(total(&scaled.sums).to_bits(), total(&expected).to_bits());
            }
        }
    }
}
