//! The topology of a solid on a voxel grid (pieces, handles, cavities), and the small holes
//! through it that a closing fills.
//!
//! A sparse cloud's fit can come back with a small tunnel through a thin wall where the points
//! lie further apart than the wall is thick: a handle no point holds open (the fandisk at 1 000
//! points without normals, genus 1–2 where the model has none; bench/RESULTS.md, "Small holes
//! of a sparse fit closed"). [`Solid::fill_holes_a_closing_fills`] finds them: the solid is closed
//! by a ball (dilated, then eroded: a hole narrower than the ball fills, a wider one and the
//! rest of the surface stay), and each connected run of voxels the closing adds is kept only
//! where it takes handles away and joins no pieces and closes off no cavity, and then peeled
//! down to a membrane across the hole (its simple voxels taken out, which changes no
//! topology), so the fill adds no clay the hole does not need. A run that only rounds a
//! concave edge leaves the Euler characteristic as it was and is passed over by a count over
//! its own box, so the whole grid is counted again only for the few runs that change it.
//! The detail patches' topology check ([`super::hierarchy`]) counts its voxels here too.
//!
//! The solid is the union of closed unit cubes, one per voxel inside: two voxels that share a
//! corner are one piece (26-connected), and the outside is connected through faces
//! (6-connected), the pairing under which `χ = pieces − handles + cavities`. A solid can be
//! read the other way ([`InsideJoins::Faces`]: the inside through faces, the outside through
//! corners), as the clay's meshes are (their ambiguous faces keep diagonally touching inside
//! samples apart, `dynaclay_core::mesh::tables`): its topology is then its complement's read
//! through corners (pieces and cavities swapped, the handles the same: Alexander duality).

/// Pieces, handles and cavities of a voxel solid.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct VoxelTopology {
    /// Connected pieces (voxels sharing a corner are connected).
    pub pieces: usize,
    /// Handles (the genus, summed over the pieces).
    pub handles: usize,
    /// Enclosed pockets of the outside.
    pub cavities: usize,
}

/// What [`Solid::fill_holes_a_closing_fills`] filled.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct HoleFill {
    /// The voxels filled (x fastest over the solid's voxels).
    pub voxels: Vec<usize>,
    /// The solid's topology before.
    pub before: VoxelTopology,
    /// The solid's topology after: the same pieces and cavities, fewer handles where any
    /// voxel was filled.
    pub after: VoxelTopology,
}

impl HoleFill {
    /// The handles the fill took away.
    #[must_use]
    pub fn handles_taken(&self) -> usize {
        self.before.handles - self.after.handles
    }
}

/// How the voxels inside a [`Solid`] join into pieces; the outside joins the other way.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InsideJoins {
    /// Voxels inside that share a corner are one piece; the outside joins through faces.
    Corners,
    /// Voxels inside join only through a shared face; the outside joins through corners, as
    /// in the clay's meshes, where two samples inside that touch diagonally are kept apart.
    Faces,
}

/// A voxel solid: `dims` voxels (x fastest), inside or not, stored with one layer of outside
/// voxels around them so that every corner's eight voxels can be read without a bounds check.
pub struct Solid {
    dims: [usize; 3],
    /// `(dims + 2)` voxels per axis, x fastest; 1 inside, 0 outside.
    padded: Vec<u8>,
    /// How the voxels inside join.
    joins: InsideJoins,
}

/// Per configuration of the eight voxels around a lattice corner (bit `dx + 2 dy + 4 dz` for
/// the voxel at `corner − 1 + (dx, dy, dz)`): the corner's share of `V − E + F − C`, the
/// corner itself, the three edges and three faces that start at it and the cube whose low
/// corner it is, each counted where a voxel inside touches it.
const EULER_SHARES: [i8; 256] = euler_shares();

const fn euler_shares() -> [i8; 256] {
    let mut table = [0i8; 256];
    let mut config = 0;
    while config < 256 {
        // 3: either offset; 2: offset 1 only (the voxel on the far side of the corner).
        let c = config;
        table[config] = any_inside(c, [3, 3, 3])
            - any_inside(c, [2, 3, 3])
            - any_inside(c, [3, 2, 3])
            - any_inside(c, [3, 3, 2])
            + any_inside(c, [3, 2, 2])
            + any_inside(c, [2, 3, 2])
            + any_inside(c, [2, 2, 3])
            - any_inside(c, [2, 2, 2]);
        config += 1;
    }
    table
}

/// Whether a voxel inside in `config` (see [`EULER_SHARES`]) has its `dx`, `dy`, `dz` in the
/// sets `masks` allow (bit 0 of a mask: offset 0 allowed; bit 1: offset 1), as 0 or 1.
const fn any_inside(config: usize, masks: [usize; 3]) -> i8 {
    let mut bit = 0;
    while bit < 8 {
        let (dx, dy, dz) = (bit & 1, (bit >> 1) & 1, (bit >> 2) & 1);
        if config & (1 << bit) != 0
            && masks[0] & (1 << dx) != 0
            && masks[1] & (1 << dy) != 0
            && masks[2] & (1 << dz) != 0
        {
            return 1;
        }
        bit += 1;
    }
    0
}

/// A voxel of [`Solid::count_components`]'s walled copy that no flood enters.
const WALL: u8 = 2;

/// The connected components of the voxels of `grid` equal to `wanted`, neighbours `steps`
/// apart; every neighbour of such a voxel must be stored (a wall or padding around them).
fn flood_count(grid: &[u8], wanted: u8, steps: &[isize]) -> usize {
    let mut seen = vec![false; grid.len()];
    let mut stack = Vec::new();
    let mut count = 0;
    for start in 0..grid.len() {
        if seen[start] || grid[start] != wanted {
            continue;
        }
        count += 1;
        seen[start] = true;
        stack.push(start);
        while let Some(at) = stack.pop() {
            for &step in steps {
                let next = at.wrapping_add_signed(step);
                if grid[next] == wanted && !seen[next] {
                    seen[next] = true;
                    stack.push(next);
                }
            }
        }
    }
    count
}

/// The 26 offsets to a voxel's neighbours that share a corner with it, and the 6 that share
/// a face, as `(dx, dy, dz)`.
fn neighbour_offsets(faces_only: bool) -> Vec<[i64; 3]> {
    let mut offsets = Vec::new();
    for dz in -1..=1i64 {
        for dy in -1..=1i64 {
            for dx in -1..=1i64 {
                let steps = dx.abs() + dy.abs() + dz.abs();
                if steps != 0 && (!faces_only || steps == 1) {
                    offsets.push([dx, dy, dz]);
                }
            }
        }
    }
    offsets
}

impl Solid {
    /// The solid of the `dims` voxels (x fastest) for which `inside` holds, its voxels
    /// inside joined through corners.
    #[must_use]
    pub fn new(dims: [usize; 3], inside: impl Fn(usize) -> bool) -> Self {
        Self::joined(dims, InsideJoins::Corners, inside)
    }

    /// The solid of the `dims` voxels (x fastest) for which `inside` holds, its voxels
    /// inside joined as `joins` says.
    #[must_use]
    pub fn joined(dims: [usize; 3], joins: InsideJoins, inside: impl Fn(usize) -> bool) -> Self {
        let [px, py, pz] = dims.map(|n| n + 2);
        let mut padded = vec![0u8; px * py * pz];
        let mut at = 0;
        for z in 0..dims[2] {
            for y in 0..dims[1] {
                let row = 1 + px * (y + 1 + py * (z + 1));
                for x in 0..dims[0] {
                    padded[row + x] = u8::from(inside(at));
                    at += 1;
                }
            }
        }
        Self {
            dims,
            padded,
            joins,
        }
    }

    /// The padded index of voxel `(x, y, z)` (each from −1 to `dims`).
    fn index(&self, [x, y, z]: [i64; 3]) -> usize {
        let [px, py, _] = self.dims.map(|n| n as i64 + 2);
        ((x + 1) + px * ((y + 1) + py * (z + 1))) as usize
    }

    /// The voxel of a padded index (each coordinate from −1 to `dims`).
    fn coords(&self, padded: usize) -> [i64; 3] {
        let [px, py, _] = self.dims.map(|n| n + 2);
        [
            (padded % px) as i64 - 1,
            ((padded / px) % py) as i64 - 1,
            (padded / (px * py)) as i64 - 1,
        ]
    }

    /// Whether voxel `(x, y, z)` of the grid is inside.
    #[must_use]
    pub fn is_inside(&self, voxel: [usize; 3]) -> bool {
        self.padded[self.index(voxel.map(|v| v as i64))] != 0
    }

    /// `V − E + F − C` of the cells whose low corners are the lattice corners `lo ..= hi`
    /// (corner `c` is the low corner of voxel `c`; corners run from 0 to `dims`), of the
    /// closed cubes of the voxels inside, or of those outside where `complement`.
    fn euler_over(&self, lo: [usize; 3], hi: [usize; 3], complement: bool) -> i64 {
        let flip = if complement { 255 } else { 0 };
        let [px, py, _] = self.dims.map(|n| n + 2);
        let plane = px * py;
        let mut chi = 0i64;
        for z in lo[2]..=hi[2] {
            for y in lo[1]..=hi[1] {
                // Corner (x, y, z)'s eight voxels are the padded voxels (x..=x+1, y..=y+1,
                // z..=z+1).
                let low = px * (y + py * z);
                let rows = [low, low + px, low + plane, low + plane + px];
                for x in lo[0]..=hi[0] {
                    let mut config = 0usize;
                    for (r, &row) in rows.iter().enumerate() {
                        let bits = usize::from(self.padded[row + x])
                            | usize::from(self.padded[row + x + 1]) << 1;
                        config |= bits << (2 * r);
                    }
                    chi += i64::from(EULER_SHARES[config ^ flip]);
                }
            }
        }
        chi
    }

    /// The Euler characteristic `V − E + F − C` of the union of the closed unit cubes of the
    /// voxels inside (the solid's through corners, however its voxels join).
    #[must_use]
    pub fn euler_characteristic(&self) -> i64 {
        self.euler_over([0; 3], self.dims, false)
    }

    /// The change in the solid's Euler characteristic over the corners `lo ..= hi` (see
    /// [`Solid::euler_over`]) as its voxels join: read off the outside's closed cubes where
    /// the inside joins through faces, whose characteristic is the complement's less one.
    /// Only differences of two such counts mean anything.
    fn euler_share_over(&self, lo: [usize; 3], hi: [usize; 3]) -> i64 {
        self.euler_over(lo, hi, self.joins == InsideJoins::Faces)
    }

    /// The pieces, handles and cavities of the solid, its voxels inside joined as it says.
    #[must_use]
    pub fn topology(&self) -> VoxelTopology {
        match self.joins {
            InsideJoins::Corners => self.topology_through_corners(),
            InsideJoins::Faces => {
                // The complement over the padded grid, padded again, read through corners.
                let complement = Solid::new(self.dims.map(|n| n + 2), |at| self.padded[at] == 0);
                let dual = complement.topology_through_corners();
                VoxelTopology {
                    pieces: dual.cavities,
                    handles: dual.handles,
                    cavities: dual.pieces.saturating_sub(1),
                }
            }
        }
    }

    /// [`Solid::topology`] with the voxels inside joined through corners.
    fn topology_through_corners(&self) -> VoxelTopology {
        let pieces = self.count_components(true);
        // The padding joins every outside voxel on the grid's border into one component.
        let cavities = self.count_components(false).saturating_sub(1);
        let handles = pieces as i64 + cavities as i64 - self.euler_characteristic();
        VoxelTopology {
            pieces,
            handles: handles.max(0) as usize,
            cavities,
        }
    }

    /// The padded voxels copied into a grid with one more layer around them, marked [`WALL`],
    /// and that grid's dimensions: a flood of the outside that does not enter the wall has
    /// every neighbour of a voxel it reaches stored.
    fn walled(&self) -> (Vec<u8>, [usize; 3]) {
        let [px, py, pz] = self.dims.map(|n| n + 2);
        let [wx, wy, wz] = [px + 2, py + 2, pz + 2];
        let mut walled = vec![WALL; wx * wy * wz];
        for z in 0..pz {
            for y in 0..py {
                let from = px * (y + py * z);
                let to = 1 + wx * (y + 1 + wy * (z + 1));
                walled[to..to + px].copy_from_slice(&self.padded[from..from + px]);
            }
        }
        (walled, [wx, wy, wz])
    }

    /// Connected components of the voxels inside (`inside`, through corners) or of the
    /// outside with its padding (through faces).
    fn count_components(&self, inside: bool) -> usize {
        if inside {
            // A voxel inside is never on the padding, so all its neighbours are stored.
            let [px, py, _] = self.dims.map(|n| n + 2);
            let steps: Vec<isize> = neighbour_offsets(false)
                .iter()
                .map(|o| (o[0] + px as i64 * (o[1] + py as i64 * o[2])) as isize)
                .collect();
            flood_count(&self.padded, 1, &steps)
        } else {
            // The outside is flooded in a copy with one more layer, a wall the flood does
            // not enter, so every voxel it reaches has its face neighbours stored.
            let (walled, [wx, wy, _]) = self.walled();
            let steps: Vec<isize> = neighbour_offsets(true)
                .iter()
                .map(|o| (o[0] + wx as i64 * (o[1] + wy as i64 * o[2])) as isize)
                .collect();
            flood_count(&walled, 0, &steps)
        }
    }

    /// The voxels outside that the outside through the padding does not reach (the
    /// cavities' voxels, the outside joined as the solid says: through faces where the inside
    /// joins through corners, through corners where it joins through faces), x fastest over
    /// the solid's voxels.
    #[must_use]
    pub fn cavity_voxels(&self) -> Vec<usize> {
        // Flooded in a copy with one more layer, a wall the flood does not enter, from the
        // padding's first voxel.
        let (walled, [wx, wy, _]) = self.walled();
        let steps: Vec<isize> = neighbour_offsets(self.joins == InsideJoins::Corners)
            .iter()
            .map(|o| (o[0] + wx as i64 * (o[1] + wy as i64 * o[2])) as isize)
            .collect();
        let start = 1 + wx * (1 + wy);
        let mut reached = vec![false; walled.len()];
        reached[start] = true;
        let mut stack = vec![start];
        while let Some(at) = stack.pop() {
            for &step in &steps {
                let next = at.wrapping_add_signed(step);
                if walled[next] == 0 && !reached[next] {
                    reached[next] = true;
                    stack.push(next);
                }
            }
        }
        let mut cavities = Vec::new();
        let mut at = 0;
        for z in 0..self.dims[2] {
            for y in 0..self.dims[1] {
                let row = 2 + wx * (y + 2 + wy * (z + 2));
                for x in 0..self.dims[0] {
                    if walled[row + x] == 0 && !reached[row + x] {
                        cavities.push(at);
                    }
                    at += 1;
                }
            }
        }
        cavities
    }

    /// How many voxels are inside.
    #[must_use]
    pub fn inside_count(&self) -> usize {
        self.padded.iter().filter(|&&v| v != 0).count()
    }

    /// The set `from` (padded indices marked 1) grown by the ball of `offsets`: each marked
    /// voxel with an unmarked face neighbour marks every voxel of the grid within the ball of
    /// it.
    fn dilated(&self, from: &[u8], offsets: &[[i64; 3]]) -> Vec<u8> {
        let mut grown = from.to_vec();
        let [px, py, _] = self.dims.map(|n| n + 2);
        let faces = [1, px, px * py];
        let limit = self.dims.map(|n| n as i64);
        let within = |v: [i64; 3]| (0..3).all(|a| v[a] >= -1 && v[a] <= limit[a]);
        for at in 0..from.len() {
            if from[at] == 0 {
                continue;
            }
            // A step off the stored voxels is no border; a step along x off the padding's
            // end lands on the padding of the next or last row, marked as this voxel is
            // wherever the padding is marked.
            let on_border = faces.iter().any(|&step| {
                at.checked_sub(step).is_some_and(|n| from[n] == 0)
                    || from.get(at + step).is_some_and(|&v| v == 0)
            });
            if !on_border {
                continue;
            }
            let c = self.coords(at);
            for o in offsets {
                let n = [c[0] + o[0], c[1] + o[1], c[2] + o[2]];
                if within(n) {
                    grown[self.index(n)] = 1;
                }
            }
        }
        grown
    }

    /// The 27 voxels around padded voxel `at` (itself at 13), `dx + 3 dy + 9 dz` for the
    /// offset `(dx − 1, dy − 1, dz − 1)`, 1 inside.
    fn neighbourhood(&self, at: usize) -> [u8; 27] {
        let [px, py, _] = self.dims.map(|n| n + 2);
        let mut around = [0u8; 27];
        for (k, value) in around.iter_mut().enumerate() {
            let (dx, dy, dz) = (k % 3, (k / 3) % 3, k / 9);
            *value = self.padded[at + dx + px * (dy + py * dz) - 1 - px - px * py];
        }
        around
    }

    /// Whether the voxel inside at padded index `at` (not on the padding) is simple: taking
    /// it out changes no piece, handle or cavity. Where the inside joins through corners, it
    /// is where the voxels inside around it are one piece (through corners) and the outside
    /// voxels that share a face or an edge with it, connected through faces among themselves,
    /// are one component that reaches it through a face; where the inside joins through
    /// faces, the same with the inside and the outside swapped.
    fn is_simple(&self, at: usize) -> bool {
        let around = self.neighbourhood(at);
        let offset = |k: usize| [k % 3, (k / 3) % 3, k / 9].map(|v| v as i64 - 1);
        let components = |member: &dyn Fn(usize) -> bool, faces_only: bool, seeds: &[usize]| {
            let mut seen = [false; 27];
            let mut count = 0;
            let mut stack = Vec::with_capacity(27);
            for &start in seeds {
                if seen[start] || !member(start) {
                    continue;
                }
                count += 1;
                seen[start] = true;
                stack.push(start);
                while let Some(k) = stack.pop() {
                    let a = offset(k);
                    for (next, was_seen) in seen.iter_mut().enumerate() {
                        let b = offset(next);
                        let d = [0, 1, 2].map(|i| (a[i] - b[i]).abs());
                        let steps = d[0] + d[1] + d[2];
                        let adjacent =
                            d.iter().all(|&v| v <= 1) && steps > 0 && (!faces_only || steps == 1);
                        if adjacent && !*was_seen && member(next) {
                            *was_seen = true;
                            stack.push(next);
                        }
                    }
                }
            }
            count
        };
        let all: Vec<usize> = (0..27).filter(|&k| k != 13).collect();
        let within_18 = |k: usize| {
            let o = offset(k);
            let steps = o[0].abs() + o[1].abs() + o[2].abs();
            (1..=2).contains(&steps)
        };
        let faces: Vec<usize> = (0..27)
            .filter(|&k| {
                let o = offset(k);
                o[0].abs() + o[1].abs() + o[2].abs() == 1
            })
            .collect();
        // The side that joins through corners is one piece among all 26; the side that joins
        // through faces, among the 18 that share a face or an edge and seeded from the six
        // faces, one component.
        let (through_corners, through_faces): (&dyn Fn(usize) -> bool, &dyn Fn(usize) -> bool) =
            match self.joins {
                InsideJoins::Corners => (&|k: usize| k != 13 && around[k] != 0, &|k: usize| {
                    within_18(k) && around[k] == 0
                }),
                InsideJoins::Faces => (&|k: usize| k != 13 && around[k] == 0, &|k: usize| {
                    within_18(k) && around[k] != 0
                }),
            };
        components(through_corners, false, &all) == 1
            && components(through_faces, true, &faces) == 1
    }

    /// Takes out of the solid, round by round, each voxel of `run` (padded indices, inside)
    /// that has a face outside and is simple, until none is: what is left of the run holds
    /// the solid's topology as the whole run did, a membrane across a hole.
    fn peel(&mut self, run: &[usize]) {
        let faces: Vec<usize> = {
            let [px, py, _] = self.dims.map(|n| n + 2);
            vec![1, px, px * py]
        };
        let mut changed = true;
        while changed {
            changed = false;
            for &at in run {
                if self.padded[at] == 0 {
                    continue;
                }
                let exposed = faces
                    .iter()
                    .any(|&step| self.padded[at - step] == 0 || self.padded[at + step] == 0);
                if exposed && self.is_simple(at) {
                    self.padded[at] = 0;
                    changed = true;
                }
            }
        }
    }

    /// The voxels that fill holes of the solid narrower than a ball of `radius` voxels, each
    /// where it takes handles away without joining pieces or closing off a cavity, peeled to
    /// a membrane across the hole; the solid is left with them inside. Returns them with the
    /// topology before and after.
    pub fn fill_holes_a_closing_fills(&mut self, radius: usize) -> HoleFill {
        let start = self.topology();
        let mut before = start;
        let mut filled = Vec::new();
        if before.handles == 0 {
            return HoleFill {
                voxels: filled,
                before: start,
                after: start,
            };
        }
        let r = radius as i64;
        let mut ball = Vec::new();
        for dz in -r..=r {
            for dy in -r..=r {
                for dx in -r..=r {
                    if dx * dx + dy * dy + dz * dz <= r * r {
                        ball.push([dx, dy, dz]);
                    }
                }
            }
        }
        // The closing: the outside of the dilated solid, dilated, is what the closing leaves
        // outside.
        let dilated = self.dilated(&self.padded, &ball);
        let outside: Vec<u8> = dilated.iter().map(|&v| 1 - v).collect();
        let outside_grown = self.dilated(&outside, &ball);
        let added: Vec<bool> = (0..self.padded.len())
            .map(|at| outside_grown[at] == 0 && self.padded[at] == 0)
            .collect();
        let offsets = neighbour_offsets(false);
        let limit = self.dims.map(|n| n as i64);
        let mut seen = vec![false; added.len()];
        let mut run = Vec::new();
        let mut stack = Vec::new();
        for start in 0..added.len() {
            if seen[start] || !added[start] {
                continue;
            }
            // One run of added voxels, connected through corners.
            run.clear();
            seen[start] = true;
            stack.push(start);
            while let Some(at) = stack.pop() {
                run.push(at);
                let c = self.coords(at);
                for o in &offsets {
                    let n = [c[0] + o[0], c[1] + o[1], c[2] + o[2]];
                    if (0..3).any(|a| n[a] < 0 || n[a] >= limit[a]) {
                        continue;
                    }
                    let next = self.index(n);
                    if !seen[next] && added[next] {
                        seen[next] = true;
                        stack.push(next);
                    }
                }
            }
            // The corners whose cells the run touches: its box and one more corner up.
            let mut lo = [usize::MAX; 3];
            let mut hi = [0usize; 3];
            for &at in &run {
                let c = self.coords(at);
                for a in 0..3 {
                    lo[a] = lo[a].min(c[a] as usize);
                    hi[a] = hi[a].max(c[a] as usize + 1);
                }
            }
            let chi_before = self.euler_share_over(lo, hi);
            run.iter().for_each(|&at| self.padded[at] = 1);
            let chi_after = self.euler_share_over(lo, hi);
            // A hole filled raises χ by one; a run that changes nothing is passed over
            // without counting the grid again.
            let after = if chi_after > chi_before {
                Some(self.topology())
            } else {
                None
            };
            match after {
                Some(after)
                    if after.handles < before.handles
                        && after.pieces == before.pieces
                        && after.cavities == before.cavities =>
                {
                    self.peel(&run);
                    let membrane: Vec<usize> = run
                        .iter()
                        .filter(|&&at| self.padded[at] != 0)
                        .map(|&at| {
                            let [x, y, z] = self.coords(at).map(|v| v as usize);
                            x + self.dims[0] * (y + self.dims[1] * z)
                        })
                        .collect();
                    before = after;
                    filled.extend(membrane);
                }
                _ => run.iter().for_each(|&at| self.padded[at] = 0),
            }
            if before.handles == 0 {
                break;
            }
        }
        HoleFill {
            voxels: filled,
            before: start,
            after: before,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A solid of `n³` voxels, inside where `keep(x, y, z)`.
    fn solid(n: usize, keep: impl Fn(i64, i64, i64) -> bool) -> Solid {
        Solid::new([n; 3], |at| {
            let (x, y, z) = (at % n, (at / n) % n, at / (n * n));
            keep(x as i64, y as i64, z as i64)
        })
    }

    /// A square frame in the plane z = 4..6 of a 20³ grid: outer half-width `outer`, a square
    /// hole of half-width `hole` about (10, 10).
    fn frame(outer: i64, hole: i64) -> Solid {
        solid(20, move |x, y, z| {
            let (dx, dy) = ((x - 10).abs(), (y - 10).abs());
            (4..=6).contains(&z) && dx.max(dy) <= outer && dx.max(dy) > hole
        })
    }

    /// A hollow box in a 10³ grid: walls from 2 to 7, the 4³ voxels from 3 to 6 hollow.
    fn hollow_box(joins: InsideJoins) -> Solid {
        Solid::joined([10; 3], joins, |at| {
            let [x, y, z] = [at % 10, (at / 10) % 10, at / 100];
            let inner = |v: usize| (3..=6).contains(&v);
            let outer = |v: usize| (2..=7).contains(&v);
            outer(x) && outer(y) && outer(z) && !(inner(x) && inner(y) && inner(z))
        })
    }

    #[test]
    fn the_voxel_euler_characteristic_counts_pieces_handles_and_cavities() {
        let chi = |n: usize, keep: &dyn Fn(usize, usize, usize) -> bool| {
            Solid::new([n; 3], |i| keep(i % n, (i / n) % n, i / (n * n))).euler_characteristic()
        };
        assert_eq!(chi(4, &|_, _, _| false), 0, "empty");
        assert_eq!(chi(4, &|x, y, z| (x, y, z) == (1, 1, 1)), 1, "one voxel");
        assert_eq!(chi(4, &|_, _, _| true), 1, "a solid block");
        assert_eq!(
            chi(5, &|x, y, z| y == 2 && z == 2 && x != 2),
            2,
            "two pieces"
        );
        // Two voxels that share only a corner are one piece.
        assert_eq!(
            chi(4, &|x, y, z| (x, y, z) == (1, 1, 1)
                || (x, y, z) == (2, 2, 2)),
            1
        );
        // A square ring, one voxel thick: one piece with one handle.
        let ring = |x: usize, y: usize, z: usize| {
            z == 1 && (1..=3).contains(&x) && (1..=3).contains(&y) && (x, y) != (2, 2)
        };
        assert_eq!(chi(5, &ring), 0, "a ring");
        // A hollow cube: one piece enclosing one cavity.
        let shell = |x: usize, y: usize, z: usize| {
            (1..=3).contains(&x)
                && (1..=3).contains(&y)
                && (1..=3).contains(&z)
                && (x, y, z) != (2, 2, 2)
        };
        assert_eq!(chi(5, &shell), 2, "a shell");
    }

    #[test]
    fn the_voxel_topology_counts_pieces_handles_and_cavities() {
        let cube = solid(8, |x, y, z| {
            (2..6).contains(&x) && (2..6).contains(&y) && (2..6).contains(&z)
        });
        assert_eq!(
            cube.topology(),
            VoxelTopology {
                pieces: 1,
                handles: 0,
                cavities: 0
            }
        );
        assert_eq!(cube.euler_characteristic(), 1);
        let ring = frame(6, 2);
        assert_eq!(ring.topology().handles, 1);
        assert_eq!(ring.euler_characteristic(), 0);
        // A hollow box: one piece, one cavity, χ = 2, however its voxels join.
        for joins in [InsideJoins::Corners, InsideJoins::Faces] {
            assert_eq!(
                hollow_box(joins).topology(),
                VoxelTopology {
                    pieces: 1,
                    handles: 0,
                    cavities: 1
                }
            );
        }
        // Two cubes meeting at one corner are one piece (closed cubes share the corner).
        let corner = solid(6, |x, y, z| {
            (x, y, z) == (1, 1, 1) || (x, y, z) == (2, 2, 2)
        });
        assert_eq!(corner.topology().pieces, 1);
        assert_eq!(corner.topology().handles, 0);
        // Two apart: two pieces.
        let apart = solid(6, |x, y, z| {
            (x, y, z) == (1, 1, 1) || (x, y, z) == (3, 3, 3)
        });
        assert_eq!(apart.topology().pieces, 2);
    }

    #[test]
    fn a_closing_fills_a_narrow_hole_and_keeps_a_wide_one() {
        // A hole 1 voxel across, through a plate 3 voxels thick, fills with a ball of radius
        // 2: the frame becomes a plate. (A ball of radius 2 passes through a hole 3 voxels
        // across in it: a hole is filled where the ball cannot pass.)
        let mut narrow = frame(7, 0);
        let fill = narrow.fill_holes_a_closing_fills(2);
        let filled = fill.voxels.clone();
        assert_eq!(fill.handles_taken(), 1);
        assert_eq!(narrow.topology().handles, 0);
        // Only voxels of the hole (none of the plate's outer rim) are added.
        assert!((1..=3).contains(&filled.len()), "{} voxels", filled.len());
        assert!(
            filled
                .iter()
                .all(|&at| at % 20 == 10 && (at / 20) % 20 == 10)
        );
        // A hole 9 voxels across stays.
        let mut wide = frame(8, 4);
        let fill = wide.fill_holes_a_closing_fills(2);
        assert_eq!((fill.voxels.len(), fill.handles_taken()), (0, 0));
        assert_eq!(wide.topology().handles, 1);
    }

    #[test]
    fn a_simple_voxel_changes_no_topology_and_a_peeled_plug_is_a_membrane() {
        // A voxel on a block's face is simple; the one voxel bridging a ring's gap is not
        // (taking it out opens the handle), nor is a voxel joining two pieces.
        let block = solid(8, |x, y, z| {
            (2..6).contains(&x) && (2..6).contains(&y) && (2..6).contains(&z)
        });
        assert!(block.is_simple(block.index([2, 3, 3])));
        let ring = frame(4, 0);
        let mut closed = frame(4, 0);
        let centre = closed.index([10, 10, 5]);
        closed.padded[centre] = 1;
        assert_eq!(ring.topology().handles, 1);
        assert_eq!(closed.topology().handles, 0);
        // The plug's middle voxel: its inside neighbours are one piece, but the outside
        // above and below it are two.
        assert!(!closed.is_simple(centre));
        let bridge = solid(6, |x, y, z| y == 2 && z == 2 && (1..=3).contains(&x));
        assert!(!bridge.is_simple(bridge.index([2, 2, 2])));
        // A plug filling a one-voxel hole through a plate three thick peels to one voxel.
        let mut plugged = frame(4, 0);
        let run: Vec<usize> = (4..=6).map(|z| plugged.index([10, 10, z])).collect();
        run.iter().for_each(|&at| plugged.padded[at] = 1);
        plugged.peel(&run);
        let left = run.iter().filter(|&&at| plugged.padded[at] != 0).count();
        assert_eq!(left, 1);
        assert_eq!(plugged.topology().handles, 0);
    }

    /// A plate four voxels thick (z = 4 ..= 7) about (10, 10) of a 20³ grid with a pinhole:
    /// a well two deep from below at (10, 10) and one from above at (11, 11), touching only at
    /// a corner.
    fn pinholed_plate(joins: InsideJoins) -> Solid {
        Solid::joined([20; 3], joins, |at| {
            let (x, y, z) = ((at % 20) as i64, ((at / 20) % 20) as i64, (at / 400) as i64);
            let on_plate = (4..=7).contains(&z) && (x - 10).abs() <= 4 && (y - 10).abs() <= 4;
            let well = ((x, y) == (10, 10) && z <= 5) || ((x, y) == (11, 11) && z >= 6);
            on_plate && !well
        })
    }

    #[test]
    fn a_solid_read_as_its_mesh_keeps_voxels_that_touch_diagonally_apart() {
        // Two voxels that share a corner: one piece through corners, two through faces.
        let corner = |joins| {
            Solid::joined([6; 3], joins, |at| at == 1 + 6 + 36 || at == 2 + 12 + 72).topology()
        };
        assert_eq!(corner(InsideJoins::Corners).pieces, 1);
        assert_eq!(
            corner(InsideJoins::Faces),
            VoxelTopology {
                pieces: 2,
                handles: 0,
                cavities: 0
            }
        );
        // The pinhole: the outside passes only through a corner, so the plate has no hole
        // through corners and one through faces, as its mesh shows it.
        assert_eq!(pinholed_plate(InsideJoins::Corners).topology().handles, 0);
        assert_eq!(
            pinholed_plate(InsideJoins::Faces).topology(),
            VoxelTopology {
                pieces: 1,
                handles: 1,
                cavities: 0
            }
        );
        // The ring reads the same either way.
        let shell = hollow_box(InsideJoins::Faces);
        let mut ring = frame(6, 2);
        ring.joins = InsideJoins::Faces;
        assert_eq!(ring.topology().handles, 1);
        // The hollow box's cavity is its 4³ inner voxels either way; the plate has none.
        let inner = |at: usize| {
            [at % 10, (at / 10) % 10, at / 100]
                .iter()
                .all(|v| (3..=6).contains(v))
        };
        let cavity = shell.cavity_voxels();
        assert_eq!(cavity.len(), 64);
        assert!(cavity.iter().all(|&at| inner(at)));
        ring.joins = InsideJoins::Corners;
        assert!(ring.cavity_voxels().is_empty());
        assert!(
            pinholed_plate(InsideJoins::Faces)
                .cavity_voxels()
                .is_empty()
        );
        // A pocket closed off through faces but open through a corner: a cavity only where the
        // inside joins through corners (the outside then joins through faces).
        let pocket = |joins| {
            Solid::joined([8; 3], joins, |at| {
                let [x, y, z] = [at % 8, (at / 8) % 8, at / 64];
                let block = [x, y, z].iter().all(|v| (2..=4).contains(v));
                block && [x, y, z] != [3, 3, 3] && [x, y, z] != [4, 4, 4]
            })
        };
        assert_eq!(pocket(InsideJoins::Corners).cavity_voxels().len(), 1);
        assert!(pocket(InsideJoins::Faces).cavity_voxels().is_empty());
        // Read through faces, the closing fills the pinhole with a voxel or two, and the
        // plate is left without a hole.
        let mut plate = pinholed_plate(InsideJoins::Faces);
        let fill = plate.fill_holes_a_closing_fills(2);
        assert_eq!(fill.handles_taken(), 1);
        assert!((1..=2).contains(&fill.voxels.len()), "{:?}", fill.voxels);
        assert_eq!(plate.topology().handles, 0);
        assert_eq!(fill.after, plate.topology());
    }

    #[test]
    fn a_closing_does_not_join_pieces() {
        // Two slabs two voxels apart: the closing would join them, which takes no handle.
        let mut slabs = solid(16, |x, y, z| {
            (3..13).contains(&x) && (3..13).contains(&y) && (z == 5 || z == 8)
        });
        assert_eq!(slabs.topology().pieces, 2);
        let fill = slabs.fill_holes_a_closing_fills(2);
        assert_eq!((fill.voxels.len(), fill.handles_taken()), (0, 0));
        // The same slabs beside a ring: the ring's hole is filled, the slabs stay apart.
        let mut both = solid(32, |x, y, z| {
            let slabs = (3..13).contains(&x) && (3..13).contains(&y) && (z == 5 || z == 8);
            let (dx, dy) = ((x - 22).abs(), (y - 22).abs());
            let ring = (4..=6).contains(&z) && dx.max(dy) <= 5 && dx.max(dy) > 0;
            slabs || ring
        });
        assert_eq!(both.topology().handles, 1);
        let fill = both.fill_holes_a_closing_fills(2);
        assert_eq!(fill.handles_taken(), 1);
        assert!(fill.voxels.iter().all(|&at| (at % 32) >= 16));
        assert_eq!(fill.after, both.topology());
        assert_eq!(
            both.topology(),
            VoxelTopology {
                pieces: 3,
                handles: 0,
                cavities: 0
            }
        );
    }
}
