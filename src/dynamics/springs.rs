//! Density-spring forces on a mass grid: a spring between neighbours `i`, `j` pulls with
//! `k_ij ((d_j − d_i) − (r_j − r_i))` along the density axis only, with `k_ij` the mean of the
//! two points' stiffness times the neighbourhood weight (1, 1/√2, 1/√3 for face, edge and
//! corner springs). A neighbour outside the grid is fixed at its rest density, so the spring
//! to it pulls with `k_i (r_i − d_i)`. Each spring is evaluated from both ends, row by row, so
//! the inner loops are contiguous and vectorise.

use super::material::Neighbourhood;

/// Offsets of the neighbourhood with their weights.
fn offsets(nb: Neighbourhood) -> impl Iterator<Item = ([i64; 3], f32)> {
    let max_order = match nb {
        Neighbourhood::Six => 1,
        Neighbourhood::Eighteen => 2,
        Neighbourhood::TwentySix => 3,
    };
    (-1..=1_i64).flat_map(move |z| {
        (-1..=1_i64).flat_map(move |y| {
            (-1..=1_i64).filter_map(move |x| {
                let order = x.abs() + y.abs() + z.abs();
                (order >= 1 && order <= max_order).then(|| ([x, y, z], 1.0 / (order as f32).sqrt()))
            })
        })
    })
}

/// `force += spring forces` for densities `d`, rest densities `rest` and per-point
/// `stiffness` on a grid of `dims` (x fastest). `e` is scratch of the same length.
pub(crate) fn add_spring_forces(
    dims: [usize; 3],
    d: &[f32],
    rest: &[f32],
    stiffness: &[f32],
    nb: Neighbourhood,
    e: &mut [f32],
    force: &mut [f32],
) {
    let [mx, my, mz] = dims;
    for ((e, &d), &r) in e.iter_mut().zip(d).zip(rest) {
        *e = d - r;
    }
    let e = &*e;
    for (o, w) in offsets(nb) {
        let half_w = 0.5 * w;
        // x range of points whose neighbour is inside along x.
        let lo = (-o[0]).max(0) as usize;
        let hi = (mx as i64 - o[0].max(0)).max(lo as i64) as usize;
        for k in 0..mz {
            for j in 0..my {
                let row = (j + my * k) * mx;
                let (j2, k2) = (j as i64 + o[1], k as i64 + o[2]);
                let f = &mut force[row..row + mx];
                let ee = &e[row..row + mx];
                let kk = &stiffness[row..row + mx];
                if j2 < 0 || j2 >= my as i64 || k2 < 0 || k2 >= mz as i64 {
                    for ((f, &e), &k) in f.iter_mut().zip(ee).zip(kk) {
                        *f -= w * k * e;
                    }
                    continue;
                }
                let nrow = (j2 as usize + my * k2 as usize) * mx;
                let (nlo, nhi) = ((lo as i64 + o[0]) as usize, (hi as i64 + o[0]) as usize);
                let en = &e[nrow + nlo..nrow + nhi];
                let kn = &stiffness[nrow + nlo..nrow + nhi];
                for ((((f, &e), &k), &e2), &k2) in f[lo..hi]
                    .iter_mut()
                    .zip(&ee[lo..hi])
                    .zip(&kk[lo..hi])
                    .zip(en)
                    .zip(kn)
                {
                    *f += half_w * (k + k2) * (e2 - e);
                }
                for i in (0..lo).chain(hi..mx) {
                    f[i] -= w * kk[i] * ee[i];
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn neighbourhoods_have_the_right_sizes() {
        assert_eq!(offsets(Neighbourhood::Six).count(), 6);
        assert_eq!(offsets(Neighbourhood::Eighteen).count(), 18);
        assert_eq!(offsets(Neighbourhood::TwentySix).count(), 26);
    }

    #[test]
    fn springs_match_a_direct_sum_and_vanish_at_rest() {
        let dims = [5, 4, 3];
        let n: usize = dims.iter().product();
        let d: Vec<f32> = (0..n).map(|i| ((i * 7) % 5) as f32 * 0.1).collect();
        let rest: Vec<f32> = (0..n).map(|i| ((i * 3) % 4) as f32 * 0.05).collect();
        let stiff: Vec<f32> = (0..n).map(|i| 1.0 + (i % 3) as f32).collect();
        for nb in [
            Neighbourhood::Six,
            Neighbourhood::Eighteen,
            Neighbourhood::TwentySix,
        ] {
            let mut e = vec![0.0; n];
            let mut f = vec![0.0; n];
            add_spring_forces(dims, &d, &rest, &stiff, nb, &mut e, &mut f);
            for idx in 0..n {
                let c = [idx % 5, (idx / 5) % 4, idx / 20];
                let mut want = 0.0;
                for (o, w) in offsets(nb) {
                    let q = [c[0] as i64 + o[0], c[1] as i64 + o[1], c[2] as i64 + o[2]];
                    let ei = d[idx] - rest[idx];
                    if (0..3).all(|a| q[a] >= 0 && q[a] < dims[a] as i64) {
                        let qi = q[0] as usize + 5 * (q[1] as usize + 4 * q[2] as usize);
                        want += w * 0.5 * (stiff[idx] + stiff[qi]) * ((d[qi] - rest[qi]) - ei);
                    } else {
                        want -= w * stiff[idx] * ei;
                    }
                }
                assert!((f[idx] - want).abs() < 1e-5, "{nb:?} point {idx}");
            }
            let mut f0 = vec![0.0; n];
            add_spring_forces(dims, &d, &d, &stiff, nb, &mut e, &mut f0);
            assert!(f0.iter().all(|&v| v == 0.0));
        }
    }
}
