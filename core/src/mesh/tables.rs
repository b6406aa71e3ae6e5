//! Marching-cubes case tables, generated at compile time from one face rule, so that every
//! mesh they produce is closed and consistently oriented.
//!
//! The 256 cases are the Lorensen–Cline configurations (every in/out labelling of a cube's
//! eight corners), but the triangles are not hand-copied from a published table: a `const fn`
//! derives them from a rule applied to each cube face, and the classic tables' hole problem
//! (complementary cases resolving a shared ambiguous face in opposite ways) cannot arise.
//!
//! Conventions:
//! - Corner `c` sits at `(c & 1, (c >> 1) & 1, (c >> 2) & 1)`; a corner is *inside* when its
//!   value is greater than the iso-level, and bit `c` of the case index is set for an inside
//!   corner.
//! - Edges 0–3 run along x, 4–7 along y, 8–11 along z (see [`EDGE_CORNERS`]); each edge starts
//!   at its lower corner.
//! - Ambiguous faces (two diagonally opposite inside corners) are resolved as *separated
//!   inside corners*: the surface cuts off each inside corner on that face on its own. The rule
//!   depends only on the four corner signs of the face, which the two cells sharing the face
//!   see identically, so the two cells' surface segments on the face coincide. Each segment is
//!   one triangle edge in each cell, traversed in opposite directions, so the surface is
//!   closed, edge-manifold and consistently oriented wherever the field is outside on the
//!   grid's boundary.
//! - Inside a cube, the face segments chain into closed loops; each loop is fanned from its
//!   first vertex. Triangles wind counter-clockwise seen from outside the solid, so their
//!   right-hand normals point from inside to outside.

/// Position (x, y, z) of each cube corner, in cells.
pub const CORNER_OFFSETS: [[u32; 3]; 8] = [
    [0, 0, 0],
    [1, 0, 0],
    [0, 1, 0],
    [1, 1, 0],
    [0, 0, 1],
    [1, 0, 1],
    [0, 1, 1],
    [1, 1, 1],
];

/// The two corners of each edge, lower corner first.
pub const EDGE_CORNERS: [[u8; 2]; 12] = [
    [0, 1],
    [2, 3],
    [4, 5],
    [6, 7],
    [0, 2],
    [1, 3],
    [4, 6],
    [5, 7],
    [0, 4],
    [1, 5],
    [2, 6],
    [3, 7],
];

/// Axis (0 = x, 1 = y, 2 = z) of each edge.
pub const EDGE_AXIS: [u8; 12] = [0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 2];

/// The most triangles any case produces.
pub const MAX_CASE_TRIANGLES: usize = 5;

/// Each cube face's corners, counter-clockwise seen from outside the cube.
const FACES: [[u8; 4]; 6] = [
    [0, 4, 6, 2], // -x
    [1, 3, 7, 5], // +x
    [0, 1, 5, 4], // -y
    [2, 6, 7, 3], // +y
    [0, 2, 3, 1], // -z
    [4, 5, 7, 6], // +z
];

/// The triangles of one case: `count` triangles, each three edge numbers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CaseTriangles {
    pub count: u8,
    pub edges: [[u8; 3]; MAX_CASE_TRIANGLES],
}

/// Triangles for every case index (bit `c` set when corner `c` is inside).
pub static CASES: [CaseTriangles; 256] = build_cases();

/// The edge joining two corners that differ in exactly one coordinate.
const fn edge_between(a: u8, b: u8) -> u8 {
    let base = if a < b { a } else { b };
    match a ^ b {
        1 => base >> 1,                              // x edge: index y + 2z
        2 => 4 + (base & 1) + ((base >> 2) & 1) * 2, // y edge: index x + 2z
        4 => 8 + (base & 3),                         // z edge: index x + 2y
        _ => panic!("corners are not adjacent"),
    }
}

const fn build_cases() -> [CaseTriangles; 256] {
    let empty = CaseTriangles {
        count: 0,
        edges: [[0; 3]; MAX_CASE_TRIANGLES],
    };
    let mut table = [empty; 256];
    let mut case = 0;
    while case < 256 {
        table[case] = build_case(case as u8);
        case += 1;
    }
    table
}

const fn build_case(case: u8) -> CaseTriangles {
    const NONE: u8 = u8::MAX;
    // next[e]: the edge where the surface loop goes after crossing edge e.
    let mut next = [NONE; 12];
    let mut face = 0;
    while face < 6 {
        let corners = FACES[face];
        // Crossings around the face, in counter-clockwise order.
        let mut crossing = [0u8; 4];
        let mut enters = [false; 4];
        let mut count = 0;
        let mut i = 0;
        while i < 4 {
            let a = corners[i];
            let b = corners[(i + 1) % 4];
            let a_in = (case >> a) & 1 == 1;
            let b_in = (case >> b) & 1 == 1;
            if a_in != b_in {
                crossing[count] = edge_between(a, b);
                enters[count] = b_in;
                count += 1;
            }
            i += 1;
        }
        // Separated-inside rule: each run of inside corners gets its own segment, from the
        // crossing that enters it to the crossing that leaves it. Crossings alternate, so the
        // leaving crossing is the next one around the face.
        let mut k = 0;
        while k < count {
            if enters[k] {
                next[crossing[k] as usize] = crossing[(k + 1) % count];
            }
            k += 1;
        }
        face += 1;
    }

    let mut out = CaseTriangles {
        count: 0,
        edges: [[0; 3]; MAX_CASE_TRIANGLES],
    };
    let mut visited = [false; 12];
    let mut start = 0;
    while start < 12 {
        if next[start] != NONE && !visited[start] {
            // Collect the loop.
            let mut ring = [0u8; 12];
            let mut len = 0;
            let mut cur = start as u8;
            loop {
                visited[cur as usize] = true;
                ring[len] = cur;
                len += 1;
                cur = next[cur as usize];
                if cur as usize == start {
                    break;
                }
            }
            // Fan it from an apex none of whose diagonals joins two edges of one face. Such a
            // diagonal could be made by the neighbouring cell too (a loop that crosses an
            // ambiguous face twice), giving an edge with four triangles; any other diagonal
            // belongs to this cell alone, so the mesh stays edge-manifold.
            let apex = fan_apex(&ring, len);
            let mut k = 1;
            while k + 1 < len {
                assert!(
                    (out.count as usize) < MAX_CASE_TRIANGLES,
                    "a case needs more triangles than MAX_CASE_TRIANGLES"
                );
                out.edges[out.count as usize] = [
                    ring[apex],
                    ring[(apex + k) % len],
                    ring[(apex + k + 1) % len],
                ];
                out.count += 1;
                k += 1;
            }
        }
        start += 1;
    }
    out
}

/// Bit f set when edge e lies on face f.
const EDGE_FACES: [u8; 12] = edge_faces();

const fn edge_faces() -> [u8; 12] {
    let mut mask = [0u8; 12];
    let mut f = 0;
    while f < 6 {
        let mut i = 0;
        while i < 4 {
            let e = edge_between(FACES[f][i], FACES[f][(i + 1) % 4]);
            mask[e as usize] |= 1 << f;
            i += 1;
        }
        f += 1;
    }
    mask
}

/// The first loop position from which a fan makes no diagonal between two edges of one face.
const fn fan_apex(ring: &[u8; 12], len: usize) -> usize {
    let mut apex = 0;
    while apex < len {
        let mut ok = true;
        let mut j = 0;
        while j < len {
            let neighbour = j == apex || j == (apex + 1) % len || j == (apex + len - 1) % len;
            if !neighbour && EDGE_FACES[ring[apex] as usize] & EDGE_FACES[ring[j] as usize] != 0 {
                ok = false;
            }
            j += 1;
        }
        if ok {
            return apex;
        }
        apex += 1;
    }
    panic!("no valid fan apex for a loop");
}

#[cfg(test)]
// The case number is both an index and a bit pattern here.
#[allow(clippy::needless_range_loop)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    fn corner_position(c: u8) -> [f32; 3] {
        let o = CORNER_OFFSETS[c as usize];
        [o[0] as f32, o[1] as f32, o[2] as f32]
    }

    fn edge_midpoint(e: u8) -> [f32; 3] {
        let [a, b] = EDGE_CORNERS[e as usize];
        let (pa, pb) = (corner_position(a), corner_position(b));
        [
            (pa[0] + pb[0]) / 2.0,
            (pa[1] + pb[1]) / 2.0,
            (pa[2] + pb[2]) / 2.0,
        ]
    }

    #[test]
    fn edge_numbering_matches_corner_pairs() {
        for (e, [a, b]) in EDGE_CORNERS.iter().enumerate() {
            assert_eq!(edge_between(*a, *b) as usize, e);
            assert_eq!((a ^ b).trailing_zeros() as u8, EDGE_AXIS[e]);
            assert!(a < b);
        }
    }

    #[test]
    fn trivial_cases_are_empty_and_complements_have_matching_size() {
        assert_eq!(CASES[0].count, 0);
        assert_eq!(CASES[255].count, 0);
        for case in 1..255usize {
            assert!(
                CASES[case].count > 0,
                "case {case} has a crossing but no triangle"
            );
        }
        // Single corner: one triangle cutting that corner off.
        for c in 0..8 {
            assert_eq!(CASES[1 << c].count, 1);
        }
    }

    #[test]
    fn every_case_uses_exactly_its_crossing_edges() {
        for case in 0..256usize {
            let mut used = [false; 12];
            let t = &CASES[case];
            for tri in &t.edges[..t.count as usize] {
                for &e in tri {
                    used[e as usize] = true;
                }
            }
            for (e, [a, b]) in EDGE_CORNERS.iter().enumerate() {
                let crosses = ((case >> a) & 1) != ((case >> b) & 1);
                assert_eq!(used[e], crosses, "case {case} edge {e}");
            }
        }
    }

    #[test]
    fn each_case_surface_has_boundary_only_on_cube_faces_and_consistent_winding() {
        // Within one cube, an interior (fan) edge is used twice in opposite directions; a
        // face segment once. Face segments must join two edges that lie on a common face.
        for case in 0..256usize {
            let t = &CASES[case];
            let mut directed: HashMap<(u8, u8), i32> = HashMap::new();
            for tri in &t.edges[..t.count as usize] {
                for k in 0..3 {
                    let (a, b) = (tri[k], tri[(k + 1) % 3]);
                    *directed.entry((a, b)).or_default() += 1;
                }
            }
            for (&(a, b), &n) in &directed {
                assert_eq!(n, 1, "case {case}: directed edge {a}->{b} used {n} times");
                if !directed.contains_key(&(b, a)) {
                    let (ma, mb) = (edge_midpoint(a), edge_midpoint(b));
                    let shares_face = (0..3).any(|ax| ma[ax] == mb[ax] && ma[ax] != 0.5);
                    assert!(
                        shares_face,
                        "case {case}: open edge {a}->{b} crosses the cube"
                    );
                }
            }
        }
    }

    #[test]
    fn no_diagonal_joins_two_edges_of_one_face() {
        // An edge between vertices on one cube face must be a face segment (used once here,
        // once by the neighbour); diagonals inside the cube must not lie on a face.
        for case in 0..256usize {
            let t = &CASES[case];
            let mut uses: HashMap<(u8, u8), i32> = HashMap::new();
            for tri in &t.edges[..t.count as usize] {
                for k in 0..3 {
                    let (a, b) = (tri[k], tri[(k + 1) % 3]);
                    *uses.entry((a.min(b), a.max(b))).or_default() += 1;
                }
            }
            for (&(a, b), &n) in &uses {
                if EDGE_FACES[a as usize] & EDGE_FACES[b as usize] != 0 {
                    assert_eq!(n, 1, "case {case}: edge {a}-{b} on a face used {n} times");
                } else {
                    assert_eq!(n, 2, "case {case}: diagonal {a}-{b} used {n} times");
                }
            }
        }
    }

    #[test]
    fn triangles_face_from_inside_to_outside() {
        // Sum of triangle normals (on edge midpoints) points from the inside corners towards
        // the outside ones.
        for case in 1..255usize {
            let t = &CASES[case];
            let mut normal = [0.0f32; 3];
            for tri in &t.edges[..t.count as usize] {
                let [p0, p1, p2] = tri.map(edge_midpoint);
                let u = [p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]];
                let v = [p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]];
                normal[0] += u[1] * v[2] - u[2] * v[1];
                normal[1] += u[2] * v[0] - u[0] * v[2];
                normal[2] += u[0] * v[1] - u[1] * v[0];
            }
            let (mut inside, mut outside) = ([0.0f32; 3], [0.0f32; 3]);
            for c in 0..8u8 {
                let p = corner_position(c);
                let target = if (case >> c) & 1 == 1 {
                    &mut inside
                } else {
                    &mut outside
                };
                for ax in 0..3 {
                    target[ax] += p[ax];
                }
            }
            let n_in = case.count_ones() as f32;
            let n_out = 8.0 - n_in;
            let dir: Vec<f32> = (0..3)
                .map(|ax| outside[ax] / n_out - inside[ax] / n_in)
                .collect();
            let dot: f32 = (0..3).map(|ax| dir[ax] * normal[ax]).sum();
            // Symmetric cases (e.g. checkerboards) have dir = 0; skip them.
            if dir.iter().any(|d| d.abs() > 1e-6) {
                assert!(dot > 0.0, "case {case}: normal {normal:?} vs {dir:?}");
            }
        }
    }
}
