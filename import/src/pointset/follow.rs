//! A point set that follows the clay while it is sculpted (Guo & Qin §4, eq. 9 and §4.3), in
//! the graphics loop: [`PointSetFollower`] is a [`MeshSink`] wrapper that, each time the
//! graphics loop hands over its refreshed copy of the clay, moves every point along its
//! normal onto the clay's current zero set, takes its new normal from the clay's gradient,
//! inserts and removes a bounded number of points where the surface stretched or shrank, and
//! publishes the points through a triple buffer a viewer reads wait-free.
//!
//! Eq. (9) moves a point with the normal speed `(∇ₚs · ṗ) / ‖∇ₓs‖` along `n`; here the field
//! is the clay itself, and the forward-Euler step that also removes any drift is a Newton
//! step on `F(x) − iso` along the gradient: `x ← x − (F(x) − iso) ∇F / ‖∇F‖²`
//! ([`FollowOptions::newton_steps`] of them per update, each at most [`MAX_STEP_SPANS`]
//! spacings long), and `n = −∇F / ‖∇F‖` (the clay's density is larger inside).
//!
//! Dynamic sampling (§4.3) uses the rules of [`super::resample`]: a point whose nearest
//! neighbour is closer than `0.7 h` goes; where a point's tangent-plane Voronoi cell reaches
//! farther than `0.72 h` a point is put at its farthest vertex and projected onto the clay;
//! the two keep the spacing within a factor 1.5 of `h` (see [`super::sampling`]). A point is
//! inserted only where it lands (after its projection) at least [`INSERT_CLEARANCE`] times
//! the removal distance from every point, so no insertion is undone by the removal rule and
//! the follower settles on a still clay, curved or not. Unlike
//! [`super::resample`], an update scans at most [`FollowOptions::scan_per_update`] points (from
//! where the last one stopped, round robin), makes at most [`FollowOptions::max_changes`]
//! insertions and removals, and never grows the set past [`FollowOptions::max_points`]; a point
//! already on the zero set costs one evaluation of the clay. So the work of one update is
//! bounded (one k-d tree, the window's queries, the projection of every point), and a
//! stretched clay is resampled over several updates, never in one long pause.
//!
//! The haptic loop never waits on it: the work runs on the graphics thread on the copy that
//! loop already keeps, new point sets arrive through a channel read with `try_recv`, and
//! publication is a wait-free buffer swap. After each change of the clay the follower takes
//! up to [`PointSetFollower::SETTLE_UPDATES`] more updates on the graphics loop's idle ticks,
//! until the points are settled (a whole round of scans inserted and removed nothing, and no
//! point moved more than [`SETTLED_MOVE_SPANS`] spacings).
//!
//! Each point's splat radius ([`PointSetView::radii`]) is the distance to the farthest vertex
//! of its tangent-plane Voronoi cell, clamped to `0.5 h ..= 1.5 h`: a disc of that radius
//! covers its whole cell, so the splats of a well-sampled surface leave no holes. Where the
//! clay curves so tightly that half a spacing is more than [`DISC_CURVATURE_RADII`] of the
//! curvature radius, the floor drops to that (a flat disc wider than it stands off the
//! surface); the covering radius is never cut, a hole being worse. Each point also carries
//! its normal's gradient ([`PointSetView::normal_gradients`], see [`super::curvature`]), for
//! a renderer to light each pixel of a splat with the normal the surface has there rather
//! than the splat's one normal (the window's splat shader does: `src/render/discs.rs`).
//! Normals are taken from the clay's gradient at every update; a normal's gradient is
//! refreshed whenever its point moves and whenever the scan passes it.

// NOTE: index loops over parallel per-point arrays read clearer than zipped iterators here.
#![allow(clippy::needless_range_loop)]

use std::num::NonZero;

use crossbeam::channel::Receiver;
use dynaclay_loops::SnapshotWriter;
use glam::{Vec2, Vec3};
use kiddo::{ImmutableKdTree, SquaredEuclidean};

use super::curvature::{NormalGradient, normal_gradient};
use super::error::PointSetError;
use super::sampling::{
    CLEARANCE_NEIGHBOURS, INSERT_CLEARANCE, farthest_voronoi_vertex, same_sheet,
};
use super::surface::PointSet;
use dynaclay_core::field::MultiPatchField;
use dynaclay_core::mesh::{BrickOctree, MeshSink, RefreshReport};
use dynaclay_core::tools::ColourField;

/// Longest Newton step, in target spacings (a step that would go farther is cut short).
pub const MAX_STEP_SPANS: f32 = 2.0;
/// A point farther than this many spacings from the clay's surface after its Newton steps
/// (the clay was carved away under it) is removed.
pub const LOST_SPANS: f32 = 1.0;
/// The points are settled when none moved more than this many spacings in an update.
pub const SETTLED_MOVE_SPANS: f32 = 1e-3;
/// Neighbours examined per point for sampling and splat radii.
const NEIGHBOURS: usize = 16;
/// The step of the central differences that give a point's normal gradient, in target
/// spacings: small against the curvature radii a point set can show (a few spacings), large
/// against the `f32` rounding of the clay's gradient.
pub const CURVATURE_STEP_SPANS: f32 = 0.25;
/// A splat's radius stays under this fraction of the local curvature radius (unless its
/// cell needs more to be covered): a flat disc of radius `r` on a surface of curvature `κ`
/// stands `κ r² / 2` off it at its rim, a tenth of its radius at half the curvature radius.
pub const DISC_CURVATURE_RADII: f32 = 0.5;
/// A splat's radius over its cell's covering radius: a disc that just reaches its cell's
/// farthest vertex leaves that vertex on three discs' rims, where a rasteriser may light none
/// of them (a one-pixel hole); the margin puts it inside.
pub const COVER_MARGIN: f32 = 1.1;

/// How the points follow the clay.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FollowOptions {
    /// Target spacing `h`, the clay's units.
    pub target_fu: f32,
    /// Newton steps onto the zero set per point per update.
    pub newton_steps: usize,
    /// Insertions and removals per update, at most.
    pub max_changes: usize,
    /// The set never grows past this many points.
    pub max_points: usize,
    /// Points scanned for sampling and splat radii per update (round robin), at most.
    pub scan_per_update: usize,
    /// Insert where the largest empty disc's radius exceeds this many `h`.
    pub insert_above: f32,
    /// Remove where the nearest neighbour is closer than this many `h`.
    pub remove_below: f32,
    /// Insert only where the new point keeps this many times the removal distance from
    /// every point ([`INSERT_CLEARANCE`]; 0 measures the empty disc alone, which thrashes
    /// on curved clay).
    pub insert_clearance: f32,
}

impl FollowOptions {
    /// The defaults for a target spacing `h` and a set of `points` points: two Newton steps,
    /// 256 changes and 4096 points scanned per update, at most four times the points (and at
    /// least 1000), the thresholds of [`super::SamplingOptions::for_target`] and the
    /// insertion clearance [`INSERT_CLEARANCE`].
    #[must_use]
    pub fn for_spacing(target_fu: f32, points: usize) -> Self {
        let sampling = super::SamplingOptions::for_target(target_fu);
        Self {
            target_fu,
            newton_steps: 2,
            max_changes: 256,
            max_points: (4 * points).max(1000),
            scan_per_update: 4096,
            insert_above: sampling.insert_above,
            remove_below: sampling.remove_below,
            insert_clearance: INSERT_CLEARANCE,
        }
    }
}

/// Points to follow: positions, unit outward normals and colours, in the clay's units.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FollowedPoints {
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub colours: Vec<[u8; 3]>,
    /// How they follow.
    pub options: Option<FollowOptions>,
}

impl FollowedPoints {
    /// The points of a built point set, following with [`FollowOptions::for_spacing`] its
    /// spacing.
    #[must_use]
    pub fn of_set(set: &PointSet) -> Self {
        Self {
            positions: set.points.clone(),
            normals: set.normals.clone(),
            colours: set.colours.clone(),
            options: Some(FollowOptions::for_spacing(set.spacing_fu, set.len())),
        }
    }
}

/// What a viewer draws: the points, their normals, colours and splat radii.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PointSetView {
    /// Whether a point set is loaded (its points may still be empty if the clay lost them).
    pub loaded: bool,
    /// How many points the loaded set had when it arrived (the count the load reported); the
    /// points followed since are resampled to the clay's area, so `positions` may hold more or
    /// fewer.
    pub arrived: usize,
    pub positions: Vec<Vec3>,
    /// Unit outward normals.
    pub normals: Vec<Vec3>,
    /// 8-bit sRGB colours.
    pub colours: Vec<[u8; 3]>,
    /// Splat radii, the clay's units.
    pub radii: Vec<f32>,
    /// How each point's normal turns across its splat ([`super::curvature`]).
    pub normal_gradients: Vec<NormalGradient>,
    /// The target spacing `h`.
    pub spacing_fu: f32,
    /// Updates taken on this set so far.
    pub updates: u64,
    /// Whether the last update left the points settled.
    pub settled: bool,
}

/// What one update did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FollowReport {
    /// The longest move of a point onto the zero set, the clay's units.
    pub moved_max_fu: f32,
    pub inserted: usize,
    pub removed: usize,
    /// Whether the points are settled: scans over the whole set since the last change
    /// inserted and removed nothing, and nothing moved more than [`SETTLED_MOVE_SPANS`]
    /// spacings.
    pub settled: bool,
}

/// Points following a field: eq. (9) and bounded dynamic sampling per [`Self::update`].
#[derive(Clone, Debug)]
pub struct PointFollower {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    colours: Vec<[u8; 3]>,
    radii: Vec<f32>,
    normal_gradients: Vec<NormalGradient>,
    options: FollowOptions,
    /// Where the next scan starts.
    cursor: usize,
    /// Points scanned since the last change (settled once it covers the set).
    clean_scanned: usize,
    gone: Vec<bool>,
    sites: Vec<Vec2>,
    /// Points inserted in this pass: position and normal.
    added: Vec<(Vec3, Vec3)>,
    coords: Vec<[f32; 3]>,
}

/// A splat's radius from its cell's covering radius `cell_fu` and the largest curvature
/// there (per clay unit): the covering radius, raised to at least `0.5 h` where the clay is
/// flat enough (a margin over neighbouring cells) but not past [`DISC_CURVATURE_RADII`]
/// curvature radii, and at most `1.5 h`. Coverage comes first: the radius is never cut
/// below the covering radius, so where the points are sparse for the curvature the discs
/// stand off the surface rather than leave holes.
fn splat_radius(cell_fu: f32, curvature_per_fu: f32, h: f32) -> f32 {
    let bent = if curvature_per_fu > 0.0 {
        DISC_CURVATURE_RADII / curvature_per_fu
    } else {
        f32::INFINITY
    };
    let floor = (0.5 * h).min(bent);
    (COVER_MARGIN * cell_fu).clamp(floor, (1.5 * h).max(floor))
}

/// `F − iso` and `∇F` of the clay.
fn sample(field: &MultiPatchField, x: Vec3) -> (f32, Vec3) {
    let (v, g) = field.value_and_gradient(x);
    (v - field.iso(), g)
}

/// Newton steps from `x` onto the zero set of `field` (each at most `max_step` long); the
/// end point and its distance from the surface to first order, or `None` where the gradient
/// vanishes or a value is not finite.
fn project(
    field: &MultiPatchField,
    mut x: Vec3,
    steps: usize,
    max_step: f32,
) -> Option<(Vec3, f32, Vec3)> {
    for _ in 0..steps {
        let (s, g) = sample(field, x);
        let g2 = g.length_squared();
        if !(g2 > 1e-20 && g2.is_finite() && s.is_finite()) {
            return None;
        }
        let step = g * (s / g2);
        x -= step.clamp_length_max(max_step);
    }
    let (s, g) = sample(field, x);
    let gl = g.length();
    if !(gl > 1e-10 && gl.is_finite() && x.is_finite()) {
        return None;
    }
    Some((x, s.abs() / gl, -g / gl))
}

impl PointFollower {
    /// Follows `points` (positions, normals and colours of one length).
    ///
    /// # Errors
    /// [`PointSetError::LengthMismatch`] when the lengths differ;
    /// [`PointSetError::Region`] for a spacing that is not positive.
    pub fn new(points: FollowedPoints, options: FollowOptions) -> Result<Self, PointSetError> {
        let n = points.positions.len();
        if points.normals.len() != n || points.colours.len() != n {
            return Err(PointSetError::LengthMismatch);
        }
        if !(options.target_fu.is_finite() && options.target_fu > 0.0) {
            return Err(PointSetError::Region(format!(
                "target spacing {}",
                options.target_fu
            )));
        }
        let mut positions = points.positions;
        let mut normals = points.normals;
        let mut colours = points.colours;
        positions.truncate(options.max_points);
        normals.truncate(options.max_points);
        colours.truncate(options.max_points);
        Ok(Self {
            radii: vec![options.target_fu; positions.len()],
            normal_gradients: vec![NormalGradient::FLAT; positions.len()],
            positions,
            normals,
            colours,
            options,
            cursor: 0,
            clean_scanned: 0,
            gone: Vec::new(),
            sites: Vec::with_capacity(NEIGHBOURS + 8),
            added: Vec::new(),
            coords: Vec::new(),
        })
    }

    /// Positions.
    #[must_use]
    pub fn positions(&self) -> &[Vec3] {
        &self.positions
    }

    /// Unit outward normals.
    #[must_use]
    pub fn normals(&self) -> &[Vec3] {
        &self.normals
    }

    /// Colours.
    #[must_use]
    pub fn colours(&self) -> &[[u8; 3]] {
        &self.colours
    }

    /// Splat radii.
    #[must_use]
    pub fn radii(&self) -> &[f32] {
        &self.radii
    }

    /// How each point's normal turns around it.
    #[must_use]
    pub fn normal_gradients(&self) -> &[NormalGradient] {
        &self.normal_gradients
    }

    /// The options.
    #[must_use]
    pub fn options(&self) -> &FollowOptions {
        &self.options
    }

    /// One update on `field`: every point onto the zero set (eq. 9), then a scan of the next
    /// [`FollowOptions::scan_per_update`] points (round robin) that removes crowded
    /// neighbours, inserts points where the surface stretched (at most
    /// [`FollowOptions::max_changes`] changes in all) and refreshes their splat radii.
    ///
    /// # Errors
    /// [`PointSetError::Index`] when the k-d tree cannot be built.
    pub fn update(&mut self, field: &MultiPatchField) -> Result<FollowReport, PointSetError> {
        let h = self.options.target_fu;
        let mut report = FollowReport::default();
        let mut budget = self.options.max_changes;

        // Eq. (9): onto the zero set along the normal; points the clay lost are removed. A
        // point already on it (to a ten-thousandth of the spacing) costs one evaluation.
        self.gone.clear();
        self.gone.resize(self.positions.len(), false);
        for i in 0..self.positions.len() {
            let p = self.positions[i];
            let (s, g) = sample(field, p);
            let gl = g.length();
            if gl > 1e-10 && s.is_finite() && s.abs() <= 1e-4 * h * gl {
                self.normals[i] = -g / gl;
                continue;
            }
            match project(field, p, self.options.newton_steps, MAX_STEP_SPANS * h) {
                Some((x, off, n)) if off <= LOST_SPANS * h => {
                    report.moved_max_fu = report.moved_max_fu.max((x - p).length());
                    self.positions[i] = x;
                    self.normals[i] = n;
                    self.normal_gradients[i] =
                        normal_gradient(field, x, n, CURVATURE_STEP_SPANS * h)
                            .unwrap_or(NormalGradient::FLAT);
                }
                _ if budget > 0 => {
                    self.gone[i] = true;
                    budget -= 1;
                }
                _ => {}
            }
        }
        report.removed += self.compact();

        // One pass over the window: crowded neighbours go, stretched cells get a point.
        let count = self.positions.len();
        let window = self.options.scan_per_update.clamp(1, count.max(1));
        if count > 0 {
            let tree = self.tree()?;
            let want = NonZero::new(NEIGHBOURS + 1).unwrap_or(NonZero::<usize>::MIN);
            let crowd = (self.options.remove_below * h).powi(2);
            self.gone.clear();
            self.gone.resize(count, false);
            self.added.clear();
            let start = self.cursor % count;
            for step in 0..window {
                let i = (start + step) % count;
                if self.gone[i] {
                    continue;
                }
                let p = self.positions[i];
                let n = self.normals[i];
                let t1 = n.any_orthonormal_vector();
                let t2 = n.cross(t1);
                self.sites.clear();
                let found = tree
                    .query(&self.coords[i])
                    .nearest_n::<SquaredEuclidean<f32>>(want)
                    .execute();
                for r in found {
                    let j = r.item as usize;
                    if j == i
                        || self.gone[j]
                        || r.distance >= 9.0 * h * h
                        || !same_sheet(self.normals[j], n)
                    {
                        continue;
                    }
                    if r.distance < crowd && budget > 0 {
                        self.gone[j] = true;
                        budget -= 1;
                        continue;
                    }
                    let d = self.positions[j] - p;
                    self.sites.push(Vec2::new(d.dot(t1), d.dot(t2)));
                }
                for &(q, m) in &self.added {
                    let d = q - p;
                    if d.length_squared() < 9.0 * h * h && same_sheet(m, n) {
                        self.sites.push(Vec2::new(d.dot(t1), d.dot(t2)));
                    }
                }
                let v = farthest_voronoi_vertex(&self.sites, 3.0 * h);
                let r = v.length();
                let w = normal_gradient(field, p, n, CURVATURE_STEP_SPANS * h)
                    .unwrap_or(NormalGradient::FLAT);
                self.normal_gradients[i] = w;
                self.radii[i] = splat_radius(r, w.max_curvature_per_fu(), h);
                let room = budget > 0 && count + self.added.len() < self.options.max_points;
                if r <= self.options.insert_above * h || !room {
                    continue;
                }
                // An open cell (the vertex on the clipping square) is a wide hole: step in by h.
                let v = if r > 2.9 * h { v * (h / r) } else { v };
                let guess = p + v.x * t1 + v.y * t2;
                let Some((y, off, normal)) = project(
                    field,
                    guess,
                    self.options.newton_steps + 2,
                    MAX_STEP_SPANS * h,
                ) else {
                    continue;
                };
                if off > 0.1 * h
                    || (y - p).length() > 3.0 * h
                    || self.crowds(
                        &tree,
                        y,
                        normal,
                        (self.options.insert_clearance * self.options.remove_below * h).powi(2),
                    )
                {
                    continue;
                }
                let w = normal_gradient(field, y, normal, CURVATURE_STEP_SPANS * h)
                    .unwrap_or(NormalGradient::FLAT);
                self.positions.push(y);
                self.normals.push(normal);
                self.colours.push(self.colours[i]);
                self.radii.push(splat_radius(
                    self.options.insert_above * h,
                    w.max_curvature_per_fu(),
                    h,
                ));
                self.normal_gradients.push(w);
                self.added.push((y, normal));
                report.inserted += 1;
                budget -= 1;
            }
            self.cursor = (start + window) % count;
            self.gone.resize(self.positions.len(), false);
            report.removed += self.compact();
        }
        let changed = report.inserted > 0
            || report.removed > 0
            || report.moved_max_fu > SETTLED_MOVE_SPANS * h;
        self.clean_scanned = if changed {
            0
        } else {
            self.clean_scanned + window
        };
        report.settled = !changed && self.clean_scanned >= self.positions.len();
        Ok(report)
    }

    /// Whether a point at `y` with normal `normal` would have a point on its sheet (of `tree`
    /// and not marked gone, or added in this pass) closer than `clearance_sq.sqrt()`.
    fn crowds(
        &self,
        tree: &ImmutableKdTree<f32, 3>,
        y: Vec3,
        normal: Vec3,
        clearance_sq: f32,
    ) -> bool {
        let want = NonZero::new(CLEARANCE_NEIGHBOURS).unwrap_or(NonZero::<usize>::MIN);
        let near = tree
            .query(&[y.x, y.y, y.z])
            .nearest_n::<SquaredEuclidean<f32>>(want)
            .execute();
        near.iter().any(|r| {
            let j = r.item as usize;
            r.distance < clearance_sq && !self.gone[j] && same_sheet(self.normals[j], normal)
        }) || self
            .added
            .iter()
            .any(|&(q, m)| q.distance_squared(y) < clearance_sq && same_sheet(m, normal))
    }

    /// Drops the points marked in `gone`; returns how many went.
    fn compact(&mut self) -> usize {
        let before = self.positions.len();
        let mut w = 0;
        for i in 0..before {
            if !self.gone.get(i).copied().unwrap_or(false) {
                self.positions[w] = self.positions[i];
                self.normals[w] = self.normals[i];
                self.colours[w] = self.colours[i];
                self.radii[w] = self.radii[i];
                self.normal_gradients[w] = self.normal_gradients[i];
                w += 1;
            }
        }
        self.positions.truncate(w);
        self.normals.truncate(w);
        self.colours.truncate(w);
        self.radii.truncate(w);
        self.normal_gradients.truncate(w);
        self.gone.clear();
        before - w
    }

    /// A k-d tree of the positions (their coordinates kept in `coords` for the queries).
    fn tree(&mut self) -> Result<ImmutableKdTree<f32, 3>, PointSetError> {
        self.coords.clear();
        self.coords
            .extend(self.positions.iter().map(|p| [p.x, p.y, p.z]));
        ImmutableKdTree::new_from_slice(&self.coords)
            .map_err(|e| PointSetError::Index(format!("{e:?}")))
    }
}

/// A [`MeshSink`] that passes everything to `inner` and keeps a point set on the clay.
pub struct PointSetFollower<S: MeshSink> {
    inner: S,
    /// New point sets (`None`: drop the points), newest wins.
    incoming: Receiver<Option<Box<FollowedPoints>>>,
    follower: Option<PointFollower>,
    /// How many points the followed set had when it arrived.
    arrived: usize,
    writer: SnapshotWriter<PointSetView>,
    updates: u64,
    /// Idle updates still to take after the last change.
    idle_left: usize,
    settled: bool,
    /// Why the last update failed, if it did.
    last_error: Option<PointSetError>,
}

impl<S: MeshSink> PointSetFollower<S> {
    /// Idle updates taken after each change of the clay, at most (each bounded; they stop
    /// as soon as the points are settled). A large push on 36k points takes a few hundred
    /// updates to resample, as the window comes round to the stretched part.
    pub const SETTLE_UPDATES: usize = 600;

    /// Follows the point sets that arrive on `incoming` (none at first), publishing on
    /// `writer`.
    #[must_use]
    pub fn new(
        inner: S,
        incoming: Receiver<Option<Box<FollowedPoints>>>,
        writer: SnapshotWriter<PointSetView>,
    ) -> Self {
        Self {
            inner,
            incoming,
            follower: None,
            arrived: 0,
            writer,
            updates: 0,
            idle_left: 0,
            settled: true,
            last_error: None,
        }
    }

    /// The wrapped sink.
    #[must_use]
    pub fn inner(&self) -> &S {
        &self.inner
    }

    /// The points being followed.
    #[must_use]
    pub fn follower(&self) -> Option<&PointFollower> {
        self.follower.as_ref()
    }

    /// Why the last update failed, if it did.
    #[must_use]
    pub fn last_error(&self) -> Option<&PointSetError> {
        self.last_error.as_ref()
    }

    /// Takes the newest point set that arrived; true when one did.
    fn take_incoming(&mut self) -> bool {
        let mut newest = None;
        while let Ok(set) = self.incoming.try_recv() {
            newest = Some(set);
        }
        let Some(set) = newest else {
            return false;
        };
        self.arrived = set.as_ref().map_or(0, |points| points.positions.len());
        self.follower = set.and_then(|points| {
            let options = points.options?;
            match PointFollower::new(*points, options) {
                Ok(f) => Some(f),
                Err(e) => {
                    self.last_error = Some(e);
                    None
                }
            }
        });
        self.updates = 0;
        self.settled = false;
        true
    }

    /// One update on `field` and its publication.
    pub fn follow(&mut self, field: &MultiPatchField) {
        if let Some(f) = self.follower.as_mut() {
            match f.update(field) {
                Ok(report) => {
                    self.settled = report.settled;
                    self.last_error = None;
                }
                Err(e) => {
                    self.settled = true;
                    self.last_error = Some(e);
                }
            }
            self.updates += 1;
        }
        self.publish();
    }

    fn publish(&mut self) {
        let (follower, updates, settled) = (self.follower.as_ref(), self.updates, self.settled);
        let arrived = if follower.is_some() { self.arrived } else { 0 };
        self.writer.write_with(|view| {
            view.positions.clear();
            view.normals.clear();
            view.colours.clear();
            view.radii.clear();
            view.normal_gradients.clear();
            view.loaded = follower.is_some();
            view.arrived = arrived;
            view.updates = updates;
            view.settled = settled;
            view.spacing_fu = 0.0;
            if let Some(f) = follower {
                view.positions.extend_from_slice(f.positions());
                view.normals.extend_from_slice(f.normals());
                view.colours.extend_from_slice(f.colours());
                view.radii.extend_from_slice(f.radii());
                view.normal_gradients
                    .extend_from_slice(f.normal_gradients());
                view.spacing_fu = f.options().target_fu;
            }
        });
    }
}

impl<S: MeshSink> MeshSink for PointSetFollower<S> {
    fn update(&mut self, octree: &BrickOctree, report: &RefreshReport) {
        self.inner.update(octree, report);
    }

    fn paint(&mut self, octree: &BrickOctree, colour: Option<&ColourField>) {
        self.inner.paint(octree, colour);
    }

    fn field(&mut self, field: &MultiPatchField) {
        self.inner.field(field);
        self.take_incoming();
        self.follow(field);
        self.idle_left = Self::SETTLE_UPDATES;
    }

    /// The clay is replaced: the points, which sat on the old clay, are dropped (the new
    /// clay's points, if any, arrive on the channel).
    fn restart(&mut self) {
        self.inner.restart();
        self.follower = None;
        self.updates = 0;
        self.settled = true;
        self.idle_left = 0;
        self.publish();
    }

    /// Takes a point set that arrived, and settles the points on a still clay: up to
    /// [`Self::SETTLE_UPDATES`] updates after each change, none once they are settled.
    fn idle(&mut self, field: &MultiPatchField) {
        self.inner.idle(field);
        if self.take_incoming() {
            self.idle_left = Self::SETTLE_UPDATES;
            self.follow(field);
            return;
        }
        if self.idle_left > 0 && !self.settled && self.follower.is_some() {
            self.idle_left -= 1;
            self.follow(field);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::PointCloud;
    use crate::pointset::{PointSetOptions, nearest_spacings};
    use dynaclay_core::field::{BSplineLattice, fit_lattice};

    /// A clay whose surface is `|x| = radius(x / |x|)`: density `0.5 − (|x| − r) / 0.3`
    /// clamped to `0..=1`, iso-level 0.5, fitted on a lattice over `± 2`.
    fn radial_clay(radius: impl Fn(Vec3) -> f32) -> MultiPatchField {
        let spacing = 0.125;
        let dims = [35; 3];
        let mut lattice =
            BSplineLattice::zeros(dims, spacing, Vec3::splat(-2.0 - spacing)).unwrap();
        fit_lattice(&mut lattice, 2, |x| {
            let r = x.length();
            let dir = x.try_normalize().unwrap_or(Vec3::X);
            (0.5 - (r - radius(dir)) / 0.3).clamp(0.0, 1.0)
        })
        .unwrap();
        lattice.iso = 0.5;
        MultiPatchField::from(lattice)
    }

    /// A push outward around +x: the radius grows by `0.35 exp(−|d − x̂|² / 0.25)`.
    fn pushed(dir: Vec3) -> f32 {
        1.0 + 0.35 * (-(dir - Vec3::X).length_squared() / 0.25).exp()
    }

    fn sphere_points(n: usize) -> PointCloud {
        let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
        let points: Vec<Vec3> = (0..n)
            .map(|i| {
                let y = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
                let r = (1.0 - y * y).sqrt();
                let t = golden * i as f32;
                Vec3::new(r * t.cos(), y, r * t.sin())
            })
            .collect();
        PointCloud {
            normals: Some(points.clone()),
            points,
        }
    }

    fn off_surface(field: &MultiPatchField, p: Vec3) -> f32 {
        let (s, g) = sample(field, p);
        s.abs() / g.length()
    }

    /// The clay is pushed out around +x: the points move onto the new zero set along their
    /// normals, points are inserted where the surface stretched (never more than the budget
    /// per update), and once settled the spacing is within 1.5× of the target everywhere.
    #[test]
    fn points_follow_a_push_onto_the_new_zero_set_and_keep_their_spacing() {
        follow_a_push(None);
    }

    /// The same with a scan window of 300 points: more updates, the same end.
    #[test]
    fn a_small_scan_window_reaches_the_same_spacing_over_more_updates() {
        follow_a_push(Some(300));
    }

    fn follow_a_push(window: Option<usize>) {
        let cloud = sphere_points(1500);
        let (set, _) = PointSet::build(&cloud, &PointSetOptions::default()).unwrap();
        let h = set.spacing_fu;
        let before = radial_clay(|_| 1.0);
        let after = radial_clay(pushed);
        let mut points = FollowedPoints::of_set(&set);
        points.colours[0] = [255, 0, 0];
        let mut options = points.options.unwrap();
        assert_eq!(options.target_fu, h);
        if let Some(w) = window {
            options.scan_per_update = w;
        }
        let mut f = PointFollower::new(points, options).unwrap();

        let first = f.update(&before).unwrap();
        assert!(first.moved_max_fu < 0.1 * h, "{first:?}");

        let (mut inserted, mut removed, mut settled) = (0, 0, false);
        for _ in 0..400 {
            let r = f.update(&after).unwrap();
            assert!(
                r.inserted + r.removed <= options.max_changes,
                "an update stays within its budget: {r:?}"
            );
            inserted += r.inserted;
            removed += r.removed;
            if r.settled {
                settled = true;
                break;
            }
        }
        assert!(
            settled,
            "settled within 200 updates ({inserted} in, {removed} out)"
        );
        assert!(
            inserted > 50,
            "the stretched surface got points: {inserted}"
        );
        let n = f.positions().len();
        assert_eq!(n, f.normals().len());
        assert_eq!(n, f.colours().len());
        assert_eq!(n, f.radii().len());
        assert!(f.colours().contains(&[255, 0, 0]), "colours travel");

        let worst = f
            .positions()
            .iter()
            .map(|&p| off_surface(&after, p))
            .fold(0.0f32, f32::max);
        assert!(worst < 0.01 * h, "{worst} off the zero set (h = {h})");
        // The tip of the push is reached.
        let tip = f.positions().iter().map(|p| p.x).fold(f32::MIN, f32::max);
        assert!((tip - 1.35).abs() < 0.03, "tip at {tip}");
        for (p, nrm) in f.positions().iter().zip(f.normals()) {
            assert!(nrm.dot(p.normalize()) > 0.5, "outward normal {nrm} at {p}");
        }
        let spacings = nearest_spacings(f.positions(), None).unwrap();
        let (lo, hi) = spacings
            .iter()
            .fold((f32::MAX, 0.0f32), |(lo, hi), &s| (lo.min(s), hi.max(s)));
        assert!(
            lo >= h / 1.5 && hi <= 1.5 * h,
            "nearest spacings {lo}..{hi}, target {h}"
        );
        for &r in f.radii() {
            assert!((0.5 * h..=1.5 * h).contains(&r), "splat radius {r}");
        }
    }

    /// The starting block of the window (24³ knots 0.1 apart, half side 0.575 around 1.15),
    /// before and after a groove is carved along x across the middle of its top: a Remove
    /// ball of radius 0.15 centred on the top (y = 1.725) at z = 1.15, from x = 0.75 to 1.55.
    fn flat_and_grooved_block() -> (BSplineLattice, BSplineLattice) {
        use dynaclay_core::field::{Primitive, band_limited_lattice};
        use dynaclay_core::tools::{
            ApplyOptions, Clay, GeometricTool, ToolAction, ToolPose, ToolShape, apply_tool,
        };
        let spacing = 0.1;
        let flat = band_limited_lattice(
            [24; 3],
            spacing,
            Vec3::ZERO,
            &Primitive::Box {
                centre: Vec3::splat(1.15),
                half_extents: Vec3::splat(0.575),
            },
            2.0 * spacing,
            2,
        )
        .unwrap();
        let mut clay = Clay::single(flat.clone());
        let ball = GeometricTool {
            shape: ToolShape::Sphere { radius_fu: 0.15 },
            action: ToolAction::Remove,
            falloff_fu: 0.05,
        };
        for i in 0..=16 {
            let pose = ToolPose {
                position_fu: Vec3::new(0.75 + 0.05 * i as f32, 1.725, 1.15),
                rotation: glam::Quat::IDENTITY,
            };
            apply_tool(&mut clay, &ball, &pose, 0.5, &ApplyOptions::default(), None).unwrap();
        }
        (flat, clay.base().clone())
    }

    /// The vertices of `lattice`'s mesh (two cells per knot span) and their normals.
    fn mesh_vertices(lattice: &BSplineLattice) -> (Vec<Vec3>, Vec<Vec3>) {
        use dynaclay_core::mesh::SampleGrid;
        let mut octree = BrickOctree::new(SampleGrid::for_lattice(lattice, 2).unwrap());
        octree.rebuild(lattice);
        let (mut positions, mut normals) = (Vec::new(), Vec::new());
        for b in octree.bricks() {
            positions.extend_from_slice(&b.mesh.positions);
            normals.extend_from_slice(&b.mesh.normals);
        }
        (positions, normals)
    }

    /// Points loaded on the block (its mesh vertices, target spacing half a knot span, as the
    /// window loads them) follow a groove carved under them. The groove's walls are curved
    /// (radius 0.15, three spacings): an inserted point projected onto them may land nearer
    /// a neighbour than the removal distance. The follower must still settle within
    /// `SETTLE_WITHIN` updates, stay still after (no insertion or removal in `STILL_FOR`
    /// more), and cover the grooved clay: every vertex of its mesh within one spacing of a
    /// point. Without the insertion clearance (the empty disc alone decides) the same points
    /// never settle there.
    #[test]
    fn points_on_a_carved_groove_settle_and_cover_it() {
        const SETTLE_WITHIN: usize = 300;
        const STILL_FOR: usize = 30;
        let (flat, grooved) = flat_and_grooved_block();
        let (positions, normals) = mesh_vertices(&flat);
        let n = positions.len();
        let h = 0.5 * flat.spacing;
        let points = FollowedPoints {
            positions,
            normals,
            colours: vec![[200, 200, 200]; n],
            options: None,
        };
        let field = MultiPatchField::from(grooved.clone());

        let unguarded = FollowOptions {
            insert_clearance: 0.0,
            ..FollowOptions::for_spacing(h, n)
        };
        let mut f = PointFollower::new(points.clone(), unguarded).unwrap();
        let (mut inserted, mut removed, mut last) = (0, 0, FollowReport::default());
        for _ in 0..SETTLE_WITHIN {
            last = f.update(&field).unwrap();
            inserted += last.inserted;
            removed += last.removed;
            if last.settled {
                break;
            }
        }
        eprintln!(
            "without the clearance: {inserted} inserted and {removed} removed in \
             {SETTLE_WITHIN} updates, the last {last:?}"
        );
        assert!(
            !last.settled,
            "the empty disc alone thrashes on the groove: {last:?}"
        );

        let mut f = PointFollower::new(points, FollowOptions::for_spacing(h, n)).unwrap();
        let (mut inserted, mut removed, mut settled_after) = (0, 0, None);
        for k in 1..=SETTLE_WITHIN {
            let r = f.update(&field).unwrap();
            inserted += r.inserted;
            removed += r.removed;
            if r.settled {
                settled_after = Some(k);
                break;
            }
        }
        let last = f.update(&field).unwrap();
        eprintln!(
            "{n} points on the block, {} on the grooved clay: settled after {settled_after:?} \
             updates, {inserted} inserted and {removed} removed; then {last:?}",
            f.positions().len()
        );
        assert!(
            settled_after.is_some(),
            "settled within {SETTLE_WITHIN} updates ({inserted} in, {removed} out; then {last:?})"
        );
        for _ in 0..STILL_FOR {
            let r = f.update(&field).unwrap();
            assert!(
                r.inserted == 0 && r.removed == 0 && r.settled,
                "still once settled: {r:?}"
            );
        }
        assert!(
            removed > 0 && inserted > 0,
            "the groove resampled the points"
        );

        // Every vertex of the grooved clay's mesh has a point within one spacing.
        let coords: Vec<[f32; 3]> = f.positions().iter().map(|p| p.to_array()).collect();
        let tree = ImmutableKdTree::<f32, 3>::new_from_slice(&coords).unwrap();
        let (vertices, _) = mesh_vertices(&grooved);
        let (mut worst, mut worst_at) = (0.0f32, Vec3::ZERO);
        for v in &vertices {
            let d = tree
                .query(&v.to_array())
                .nearest_one::<SquaredEuclidean<f32>>()
                .execute()
                .distance
                .sqrt();
            if d > worst {
                (worst, worst_at) = (d, *v);
            }
        }
        eprintln!(
            "{} mesh vertices, the farthest {:.3} h from a point at {worst_at}",
            vertices.len(),
            worst / h
        );
        assert!(worst <= h, "a vertex {worst} from the points at {worst_at}");
        let floor = f.positions().iter().map(|p| p.y).fold(f32::MAX, f32::min);
        let in_groove = f
            .positions()
            .iter()
            .filter(|p| (p.x - 1.15).abs() < 0.2 && (p.z - 1.15).abs() < 0.05 && p.y < 1.65)
            .count();
        assert!(
            in_groove > 10 && floor < 0.6,
            "points line the groove's floor ({in_groove}) and the block's base ({floor})"
        );
    }

    /// A clay carved away under the points loses them, within the budget per update; a set
    /// of mismatched lengths is refused.
    #[test]
    fn points_the_clay_lost_go_and_bad_sets_are_refused() {
        let cloud = sphere_points(600);
        let (set, _) = PointSet::build(&cloud, &PointSetOptions::default()).unwrap();
        let mut points = FollowedPoints::of_set(&set);
        let mut options = points.options.unwrap();
        options.max_changes = 100;
        points.options = Some(options);
        let mut f = PointFollower::new(points.clone(), options).unwrap();
        let empty =
            MultiPatchField::from(BSplineLattice::zeros([8; 3], 1.0, Vec3::splat(-4.0)).unwrap());
        let r = f.update(&empty).unwrap();
        assert_eq!(r.removed, 100, "{r:?}");
        assert_eq!(f.positions().len(), 500);
        for _ in 0..5 {
            f.update(&empty).unwrap();
        }
        assert!(f.positions().is_empty());

        points.colours.pop();
        assert!(matches!(
            PointFollower::new(points, options),
            Err(PointSetError::LengthMismatch)
        ));
    }
}
