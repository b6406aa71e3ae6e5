//! Undo and redo of tool actions and force strokes, one stroke being one step, stored as
//! bitwise XOR deltas of the coefficient bricks the step touched.
//!
//! Guarantee: undoing a step restores every coefficient (density, colour and mask) bit for bit, and
//! redoing it restores the post-step bits, provided the clay was changed only through recorded
//! steps in between. Memory is bounded by [`History::budget_bytes`]: when a new step would
//! exceed it, the oldest steps are dropped first. Recording allocates (it copies the touched
//! bricks); it belongs on the simulation thread between steps, never on the haptic path.

use std::collections::{BTreeMap, VecDeque};

use super::clay::{BRICK, Clay, CoeffBox, FieldId};
use super::growth::Growth;
use crate::dynamics::Constraint;
use crate::field::{CoarsenPlan, DenseBudgetError, Patch, apply_coarsening, check_dense_room};

/// Default memory bound of the history: 256 MiB.
pub const DEFAULT_BUDGET_BYTES: usize = 256 << 20;

/// Why an undo or redo could not be applied.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum HistoryError {
    /// The step refers to a field the clay no longer has, or whose dimensions changed.
    #[error("cannot apply history step to {field:?}: {detail}")]
    FieldMismatch { field: FieldId, detail: String },
}

/// XOR of old and new coefficient bits over one brick.
#[derive(Clone, Debug, PartialEq)]
struct BrickDelta {
    field: FieldId,
    /// The field's dimensions when recorded (checked before applying).
    dims: [usize; 3],
    region: CoeffBox,
    xor: Box<[u32]>,
}

impl BrickDelta {
    fn bytes(&self) -> usize {
        std::mem::size_of::<Self>() + 4 * self.xor.len()
    }
}

/// One undoable step: every brick it changed.
#[derive(Clone, Debug, PartialEq)]
pub struct Step {
    /// What the user did ("add sphere", "grab stroke"), for menus.
    pub label: String,
    deltas: Vec<BrickDelta>,
    /// The clay's constraints before and after the step, when it changed them.
    pins: Option<Box<PinSwap>>,
    /// Detail patches the step removed (folded into coarser ones), in the order removed.
    removed: Vec<RemovedPatch>,
}

/// A detail patch a step removed: where it was and what it held before the step.
#[derive(Clone, Debug, PartialEq)]
struct RemovedPatch {
    /// Its index in the layout it was removed from.
    index: usize,
    /// The patch as the step found it.
    before: Patch,
}

impl RemovedPatch {
    fn bytes(&self) -> usize {
        std::mem::size_of::<Self>() + 4 * self.before.lattice.coeffs.len()
    }
}

/// A change of the clay's constraint list (small: the lists are kept whole).
#[derive(Clone, Debug, PartialEq)]
struct PinSwap {
    before: Vec<Constraint>,
    after: Vec<Constraint>,
}

impl PinSwap {
    fn bytes(&self) -> usize {
        let one = |c: &Constraint| {
            std::mem::size_of::<Constraint>()
                + match c {
                    Constraint::Curve { points } => 12 * points.len(),
                    _ => 0,
                }
        };
        std::mem::size_of::<Self>()
            + self
                .before
                .iter()
                .chain(&self.after)
                .map(one)
                .sum::<usize>()
    }
}

impl Step {
    /// Bytes this step holds in the history.
    #[must_use]
    pub fn bytes(&self) -> usize {
        std::mem::size_of::<Self>()
            + self.label.len()
            + self.deltas.iter().map(BrickDelta::bytes).sum::<usize>()
            + self.pins.as_ref().map_or(0, |p| p.bytes())
            + self.removed.iter().map(RemovedPatch::bytes).sum::<usize>()
    }

    /// Number of coefficients the step changed bricks of (a brick counts whole).
    #[must_use]
    pub fn coefficients(&self) -> usize {
        self.deltas.iter().map(|d| d.xor.len()).sum()
    }

    /// The boxes of density coefficients the step changed: one per recorded brick, as
    /// (patch, box) in the layout the step applies to.
    pub fn density_boxes(&self) -> impl Iterator<Item = (u16, CoeffBox)> + '_ {
        self.deltas.iter().filter_map(|d| match d.field {
            FieldId::Density(patch) => Some((patch, d.region)),
            FieldId::Colour(_) | FieldId::Mask(_) => None,
        })
    }

    /// Checks that every delta fits the clay's fields as they are.
    fn check_deltas(&self, clay: &Clay) -> Result<(), HistoryError> {
        for d in &self.deltas {
            let field = clay
                .field(d.field)
                .ok_or_else(|| HistoryError::FieldMismatch {
                    field: d.field,
                    detail: "the field no longer exists".into(),
                })?;
            if field.dims != d.dims || field.coeffs.len() != d.dims.iter().product::<usize>() {
                return Err(HistoryError::FieldMismatch {
                    field: d.field,
                    detail: format!(
                        "dimensions {:?} differ from recorded {:?}",
                        field.dims, d.dims
                    ),
                });
            }
        }
        Ok(())
    }

    /// XORs the deltas into the clay and swaps the pins: applying it twice is a no-op, so it
    /// both undoes and redoes the coefficients (the caller checked the deltas).
    fn toggle_deltas(&self, clay: &mut Clay) {
        for d in &self.deltas {
            let Some(field) = clay.field_mut(d.field) else {
                continue;
            };
            // Row by row over contiguous slices (see bench/tools.rs, undo_redo_256).
            let mut xor = d.xor.chunks_exact(d.region.dims()[0]);
            let mut row = vec![0.0; d.region.dims()[0]];
            for_each_row(d.dims, &d.region, |start, len| {
                let bits = xor.next().expect("one XOR row per region row");
                let row = &mut row[..len];
                field.coeffs.read_row(start, row);
                for (c, x) in row.iter_mut().zip(bits) {
                    *c = f32::from_bits(c.to_bits() ^ x);
                }
                field.coeffs.write_row(start, row);
            });
            field.coeffs.compact_within(d.region.min, d.region.max);
        }
        if let Some(p) = &self.pins {
            // Undo finds the list as the step left it; redo finds it as the step found it.
            clay.constraints = if clay.constraints == p.after {
                p.before.clone()
            } else {
                p.after.clone()
            };
        }
    }

    /// Gives the clay back as the step found it: the deltas on the layout the step left, then
    /// the removed patches back in their places.
    fn undo(&self, clay: &mut Clay) -> Result<(), HistoryError> {
        self.check_deltas(clay)?;
        // Each patch put back makes room for the next one's index.
        let lens = clay.density.patches.len()..;
        for (len, r) in lens.zip(self.removed.iter().rev()) {
            if r.index == 0 || r.index > len {
                return Err(HistoryError::FieldMismatch {
                    field: FieldId::Density(u16::try_from(r.index).unwrap_or(u16::MAX)),
                    detail: format!("cannot put a removed patch back among {len} patches"),
                });
            }
        }
        self.toggle_deltas(clay);
        for r in self.removed.iter().rev() {
            clay.density.patches.insert(r.index, r.before.clone());
        }
        Ok(())
    }

    /// Does the step again on the clay as it found it: the patches it removed go first, then
    /// the deltas apply on the layout it left.
    fn redo(&self, clay: &mut Clay) -> Result<(), HistoryError> {
        let mut taken = Vec::with_capacity(self.removed.len());
        for r in &self.removed {
            if r.index == 0 || r.index >= clay.density.patches.len() {
                for (index, patch) in taken.into_iter().rev() {
                    clay.density.patches.insert(index, patch);
                }
                return Err(HistoryError::FieldMismatch {
                    field: FieldId::Density(u16::try_from(r.index).unwrap_or(u16::MAX)),
                    detail: "the patch the step removed is not there".into(),
                });
            }
            taken.push((r.index, clay.density.patches.remove(r.index)));
        }
        if let Err(e) = self.check_deltas(clay) {
            for (index, patch) in taken.into_iter().rev() {
                clay.density.patches.insert(index, patch);
            }
            return Err(e);
        }
        self.toggle_deltas(clay);
        Ok(())
    }
}

/// The coefficients of brick `brick` (unclipped).
fn brick_box(brick: [usize; 3]) -> CoeffBox {
    CoeffBox {
        min: brick.map(|b| b * BRICK),
        max: brick.map(|b| (b + 1) * BRICK - 1),
    }
}

/// Whether a delta or saved brick of `field`, recorded on a lattice of `dims`, moves when
/// the clay grows by `growth`.
fn moves_with(field: FieldId, dims: [usize; 3], growth: &Growth) -> bool {
    matches!(
        field,
        FieldId::Density(0) | FieldId::Colour(_) | FieldId::Mask(0)
    ) && dims == growth.old_dims
}

/// Visits the rows of `region` in a lattice of `dims` as (first linear index, length).
fn for_each_row(dims: [usize; 3], region: &CoeffBox, mut f: impl FnMut(usize, usize)) {
    let len = region.max[0] + 1 - region.min[0];
    for k in region.min[2]..=region.max[2] {
        for j in region.min[1]..=region.max[1] {
            f(region.min[0] + dims[0] * (j + dims[1] * k), len);
        }
    }
}

/// Visits the linear indices of `region` in a lattice of `dims`, x fastest.
#[cfg(test)]
fn for_each_index(dims: [usize; 3], region: &CoeffBox, mut f: impl FnMut(usize)) {
    for k in region.min[2]..=region.max[2] {
        for j in region.min[1]..=region.max[1] {
            let row = dims[0] * (j + dims[1] * k);
            for i in region.min[0]..=region.max[0] {
                f(row + i);
            }
        }
    }
}

/// Collects the pre-step values of every brick a step is about to change.
///
/// Call [`StepRecorder::touch`] with each region *before* writing to it (a tool application,
/// each simulation step of a stroke); [`StepRecorder::finish`] then compares with the clay.
#[derive(Debug, Default)]
pub struct StepRecorder {
    label: String,
    /// Old bits of each touched brick, keyed by field and brick index.
    old: BTreeMap<(FieldId, [usize; 3]), SavedBrick>,
    /// The clay's constraints before the step, when the step may change them.
    pins_before: Option<Vec<Constraint>>,
    /// Detail patches removed during the step, as it found them.
    removed: Vec<RemovedPatch>,
}

/// The bits of one brick before a step.
#[derive(Debug)]
struct SavedBrick {
    region: CoeffBox,
    dims: [usize; 3],
    bits: SavedBits,
}

/// A touched brick's old bits, x fastest over its region: one word when they were all the
/// same (empty space, solid inside: what most of a large clay's bricks hold), so that
/// recording a whole clay costs its dense bricks and a few words per other brick, not its box.
#[derive(Debug)]
enum SavedBits {
    /// Every coefficient held these bits.
    Same(u32),
    /// The bits of each coefficient.
    Each(Vec<u32>),
}

impl SavedBits {
    /// The bits of coefficients `n`, … `n + len − 1` of the region, into `out`.
    fn copy_to(&self, n: usize, out: &mut [u32]) {
        match self {
            Self::Same(b) => out.fill(*b),
            Self::Each(bits) => out.copy_from_slice(&bits[n..n + out.len()]),
        }
    }

    /// Every coefficient's bits, `count` of them.
    fn expanded(&self, count: usize) -> Vec<u32> {
        match self {
            Self::Same(b) => vec![*b; count],
            Self::Each(bits) => bits.clone(),
        }
    }
}

impl StepRecorder {
    /// Starts recording a step.
    #[must_use]
    pub fn new(label: impl Into<String>) -> Self {
        Self {
            label: label.into(),
            old: BTreeMap::new(),
            pins_before: None,
            removed: Vec::new(),
        }
    }

    /// Remembers the clay's constraint list before the step changes it (once per recorder).
    pub fn touch_constraints(&mut self, clay: &Clay) {
        if self.pins_before.is_none() {
            self.pins_before = Some(clay.constraints.clone());
        }
    }

    /// Remembers the current values of the bricks of `field` that meet `region`, unless they
    /// were already remembered by this recorder. Unknown fields and empty boxes are ignored.
    pub fn touch(&mut self, clay: &Clay, field: FieldId, region: CoeffBox) {
        let Some(lattice) = clay.field(field) else {
            return;
        };
        let dims = lattice.dims;
        let Some(region) = region.clipped(dims) else {
            return;
        };
        let b0: [usize; 3] = std::array::from_fn(|a| region.min[a] / BRICK);
        let b1: [usize; 3] = std::array::from_fn(|a| region.max[a] / BRICK);
        for bk in b0[2]..=b1[2] {
            for bj in b0[1]..=b1[1] {
                for bi in b0[0]..=b1[0] {
                    let key = (field, [bi, bj, bk]);
                    if self.old.contains_key(&key) {
                        continue;
                    }
                    let Some(brick) = brick_box([bi, bj, bk]).clipped(dims) else {
                        continue;
                    };
                    let mut read = [0_u32; BRICK * BRICK * BRICK];
                    let mut n = 0;
                    let mut row = [0.0; BRICK];
                    for_each_row(dims, &brick, |start, len| {
                        lattice.coeffs.read_row(start, &mut row[..len]);
                        for (b, c) in read[n..n + len].iter_mut().zip(&row[..len]) {
                            *b = c.to_bits();
                        }
                        n += len;
                    });
                    let read = &read[..n];
                    let bits = if read.iter().all(|&b| b == read[0]) {
                        SavedBits::Same(read[0])
                    } else {
                        SavedBits::Each(read.to_vec())
                    };
                    self.old.insert(
                        key,
                        SavedBrick {
                            region: brick,
                            dims,
                            bits,
                        },
                    );
                }
            }
        }
    }

    /// Remembers every brick of every field (for whole-clay operations such as CSG between
    /// sessions).
    pub fn touch_all(&mut self, clay: &Clay) {
        let mut ids: Vec<FieldId> = (0..clay.density.patches.len())
            .map(|n| FieldId::Density(n as u16))
            .collect();
        if clay.colour.is_some() {
            ids.extend((0..4).map(FieldId::Colour));
        }
        if let Some(mask) = &clay.mask {
            ids.extend((0..mask.patches.len()).map(|n| FieldId::Mask(n as u16)));
        }
        for id in ids {
            if let Some(l) = clay.field(id) {
                let full = CoeffBox::whole(l.dims);
                self.touch(clay, id, full);
            }
        }
    }

    /// Moves the remembered bricks onto the grown base and colour field (see
    /// [`super::Growth`]), so that a stroke that grew the clay stays one step.
    pub fn regrid(&mut self, growth: &Growth) {
        let bricks = growth.pad.map(|p| p / BRICK);
        self.old = std::mem::take(&mut self.old)
            .into_iter()
            .map(|((field, brick), mut saved)| {
                if !moves_with(field, saved.dims, growth) {
                    return ((field, brick), saved);
                }
                let brick: [usize; 3] = std::array::from_fn(|a| brick[a] + bricks[a]);
                let moved = saved.region.shifted(growth.pad);
                // A brick clipped at the old lattice's far side is whole (or less clipped) on
                // the grown one: its new coefficients were empty space, zero before the step.
                let whole = brick_box(brick)
                    .clipped(growth.new_dims)
                    .expect("a moved brick lies inside the grown lattice");
                if whole == moved {
                    saved.region = whole;
                    saved.dims = growth.new_dims;
                    return ((field, brick), saved);
                }
                let mut bits = Vec::with_capacity(whole.count());
                let old_bits = saved.bits.expanded(moved.count());
                let mut old_rows = old_bits.chunks_exact(moved.dims()[0]);
                for k in whole.min[2]..=whole.max[2] {
                    for j in whole.min[1]..=whole.max[1] {
                        let kept = (moved.min[1]..=moved.max[1]).contains(&j)
                            && (moved.min[2]..=moved.max[2]).contains(&k);
                        let row = if kept { old_rows.next() } else { None };
                        for i in whole.min[0]..=whole.max[0] {
                            let at = i.checked_sub(moved.min[0]);
                            bits.push(row.and_then(|r| r.get(at?)).copied().unwrap_or(0));
                        }
                    }
                }
                saved.region = whole;
                saved.dims = growth.new_dims;
                saved.bits = SavedBits::Each(bits);
                ((field, brick), saved)
            })
            .collect();
    }

    /// Applies `plan` (a fold of a detail patch into a coarser one, see
    /// [`crate::field::plan_coarsening`]) to `clay` as part of this step: the coarser patch's
    /// rewritten coefficients become deltas, and the removed patch is kept whole as the step
    /// found it, so undo puts it back bit for bit. Later patches move down one index, here as
    /// in the clay.
    ///
    /// # Errors
    /// [`DenseBudgetError`] when the rewritten box could make more bricks of the coarser patch
    /// dense than the clay's budget leaves, with the detail patch's own dense bricks freed;
    /// nothing changes then (the detail patch stays).
    pub fn coarsen(&mut self, clay: &mut Clay, plan: &CoarsenPlan) -> Result<(), DenseBudgetError> {
        let index = plan.patch;
        let id = FieldId::Density(u16::try_from(index).unwrap_or(u16::MAX));
        if let Some((region, _)) = &plan.rewrite {
            let into = FieldId::Density(u16::try_from(plan.into).unwrap_or(u16::MAX));
            let more = clay.field(into).map_or(0, |l| {
                l.coeffs.uniform_bricks_holding(region.min, region.max)
            });
            let freed = clay.field(id).map_or(0, |l| l.coeffs.dense_brick_count());
            check_dense_room(clay.dense_brick_count() - freed, more, Some(*region))?;
        }
        if let Some((region, _)) = &plan.rewrite {
            let into = FieldId::Density(u16::try_from(plan.into).unwrap_or(u16::MAX));
            self.touch(clay, into, *region);
        }
        if let Some(lattice) = clay.field(id) {
            let whole = CoeffBox::whole(lattice.dims);
            self.touch(clay, id, whole);
        }
        let mut before = apply_coarsening(&mut clay.density, plan);
        let dims = before.lattice.dims;
        let mut remapped = BTreeMap::new();
        for ((field, brick), saved) in std::mem::take(&mut self.old) {
            match field {
                FieldId::Density(n) if usize::from(n) == index => {
                    // The bits as the step found them go back into the patch kept for undo.
                    let old_bits = saved.bits.expanded(saved.region.count());
                    let mut bits = old_bits.chunks_exact(saved.region.dims()[0]);
                    let mut values = [0.0; BRICK];
                    for_each_row(dims, &saved.region, |start, len| {
                        let row = bits.next().expect("one saved row per region row");
                        for (c, &b) in values.iter_mut().zip(row) {
                            *c = f32::from_bits(b);
                        }
                        before.lattice.coeffs.write_row(start, &values[..len]);
                    });
                }
                FieldId::Density(n) if usize::from(n) > index => {
                    remapped.insert((FieldId::Density(n - 1), brick), saved);
                }
                _ => {
                    remapped.insert((field, brick), saved);
                }
            }
        }
        self.old = remapped;
        self.removed.push(RemovedPatch { index, before });
        Ok(())
    }

    /// The union of the touched bricks of `field` (`None` if none).
    #[must_use]
    pub fn touched_box(&self, field: FieldId) -> Option<CoeffBox> {
        self.old
            .iter()
            .filter(|((f, _), _)| *f == field)
            .map(|(_, saved)| saved.region)
            .reduce(|a, b| a.union(&b))
    }

    /// Compares the remembered bricks with the clay now; `None` if nothing changed.
    #[must_use]
    pub fn finish(self, clay: &Clay) -> Option<Step> {
        let mut deltas = Vec::new();
        for (
            (field, _),
            SavedBrick {
                region,
                dims,
                bits: old,
            },
        ) in self.old
        {
            let Some(lattice) = clay.field(field) else {
                continue;
            };
            if lattice.dims != dims {
                continue;
            }
            let mut xor = Vec::with_capacity(region.count());
            let mut row = [0.0; BRICK];
            let mut old_row = [0_u32; BRICK];
            for_each_row(dims, &region, |start, len| {
                let n = xor.len();
                lattice.coeffs.read_row(start, &mut row[..len]);
                old.copy_to(n, &mut old_row[..len]);
                xor.extend(
                    row[..len]
                        .iter()
                        .zip(&old_row[..len])
                        .map(|(c, o)| c.to_bits() ^ o),
                );
            });
            if xor.iter().any(|&x| x != 0) {
                deltas.push(BrickDelta {
                    field,
                    dims,
                    region,
                    xor: xor.into_boxed_slice(),
                });
            }
        }
        let pins = self
            .pins_before
            .filter(|before| *before != clay.constraints)
            .map(|before| {
                Box::new(PinSwap {
                    before,
                    after: clay.constraints.clone(),
                })
            });
        if deltas.is_empty() && pins.is_none() && self.removed.is_empty() {
            return None;
        }
        Some(Step {
            label: self.label,
            deltas,
            pins,
            removed: self.removed,
        })
    }
}

/// The undo and redo stacks with a memory bound.
#[derive(Debug)]
pub struct History {
    undo: VecDeque<Step>,
    redo: Vec<Step>,
    /// Memory bound over both stacks, in bytes.
    pub budget_bytes: usize,
    used_bytes: usize,
    dropped_steps: usize,
}

impl Default for History {
    fn default() -> Self {
        Self::new(DEFAULT_BUDGET_BYTES)
    }
}

impl History {
    /// An empty history bounded to `budget_bytes`.
    #[must_use]
    pub fn new(budget_bytes: usize) -> Self {
        Self {
            undo: VecDeque::new(),
            redo: Vec::new(),
            budget_bytes,
            used_bytes: 0,
            dropped_steps: 0,
        }
    }

    /// Records a finished step; clears the redo stack, then drops the oldest steps until the
    /// history fits its budget (a step larger than the whole budget is not kept).
    pub fn push(&mut self, step: Step) {
        for s in self.redo.drain(..) {
            self.used_bytes -= s.bytes();
        }
        self.used_bytes += step.bytes();
        self.undo.push_back(step);
        while self.used_bytes > self.budget_bytes {
            let Some(old) = self.undo.pop_front() else {
                break;
            };
            self.used_bytes -= old.bytes();
            self.dropped_steps += 1;
        }
    }

    /// Finishes a recorder and pushes its step if anything changed; returns whether it did.
    pub fn commit(&mut self, recorder: StepRecorder, clay: &Clay) -> bool {
        match recorder.finish(clay) {
            Some(step) => {
                self.push(step);
                true
            }
            None => false,
        }
    }

    /// Undoes the latest step; returns its label, or `None` when there is nothing to undo.
    ///
    /// # Errors
    /// When the clay's fields no longer match the step (nothing is changed then).
    pub fn undo(&mut self, clay: &mut Clay) -> Result<Option<String>, HistoryError> {
        let Some(step) = self.undo.pop_back() else {
            return Ok(None);
        };
        if let Err(e) = step.undo(clay) {
            self.undo.push_back(step);
            return Err(e);
        }
        let label = step.label.clone();
        self.redo.push(step);
        Ok(Some(label))
    }

    /// Redoes the latest undone step; returns its label, or `None` when there is none.
    ///
    /// # Errors
    /// As [`History::undo`].
    pub fn redo(&mut self, clay: &mut Clay) -> Result<Option<String>, HistoryError> {
        let Some(step) = self.redo.pop() else {
            return Ok(None);
        };
        if let Err(e) = step.redo(clay) {
            self.redo.push(step);
            return Err(e);
        }
        let label = step.label.clone();
        self.undo.push_back(step);
        Ok(Some(label))
    }

    /// The step the latest [`History::undo`] took back (the next to redo), if any.
    #[must_use]
    pub fn next_redo(&self) -> Option<&Step> {
        self.redo.last()
    }

    /// The newest step done (the next to undo: the latest recorded or redone), if any.
    #[must_use]
    pub fn next_undo(&self) -> Option<&Step> {
        self.undo.back()
    }

    /// Moves every recorded delta of the base and the colour field onto the grown lattices
    /// (see [`super::Growth`]): the added coefficients are empty space that no step changed,
    /// so every step still undoes and redoes bit for bit after the clay grew. The growth
    /// itself is not a step: undo gives back the shape, the room stays.
    pub fn regrid(&mut self, growth: &Growth) {
        for step in self.undo.iter_mut().chain(self.redo.iter_mut()) {
            for d in &mut step.deltas {
                if moves_with(d.field, d.dims, growth) {
                    d.region = d.region.shifted(growth.pad);
                    d.dims = growth.new_dims;
                }
            }
        }
    }

    /// Steps that can be undone.
    #[must_use]
    pub fn undo_len(&self) -> usize {
        self.undo.len()
    }

    /// Steps that can be redone.
    #[must_use]
    pub fn redo_len(&self) -> usize {
        self.redo.len()
    }

    /// Bytes held by both stacks.
    #[must_use]
    pub fn used_bytes(&self) -> usize {
        self.used_bytes
    }

    /// Steps dropped so far to stay within the budget.
    #[must_use]
    pub fn dropped_steps(&self) -> usize {
        self.dropped_steps
    }

    /// Forgets everything (after loading another session).
    pub fn clear(&mut self) {
        self.undo.clear();
        self.redo.clear();
        self.used_bytes = 0;
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::field::BSplineLattice;

    fn clay() -> Clay {
        let mut l = BSplineLattice::zeros([20, 13, 9], 0.1, Vec3::ZERO).unwrap();
        l.coeffs.update_each(|n, c| {
            *c = (n % 7) as f32 * 0.1;
        });
        Clay::single(l)
    }

    fn edit(clay: &mut Clay, history: &mut History, region: CoeffBox, value: f32) {
        let mut rec = StepRecorder::new("set");
        rec.touch(clay, FieldId::Density(0), region);
        let l = &mut clay.density.patches[0].lattice;
        let dims = l.dims;
        for_each_index(dims, &region.clipped(dims).unwrap(), |i| {
            l.coeffs.set_flat(i, value)
        });
        history.commit(rec, clay);
    }

    /// Sets every coefficient of density patch `n` to `value(index)`.
    fn fill(clay: &mut Clay, n: usize, value: impl Fn(usize) -> f32) {
        clay.density.patches[n]
            .lattice
            .coeffs
            .update_each(|i, c| *c = value(i));
    }

    #[test]
    fn recording_a_whole_sparse_clay_keeps_one_word_per_uniform_brick_and_undoes_exactly() {
        // 256 × 256 × 64 coefficients of empty space with solid bricks and a ramp in one.
        let mut l = BSplineLattice::zeros([256, 256, 64], 0.1, Vec3::ZERO).unwrap();
        for k in 8..16 {
            for j in 8..24 {
                for i in 8..16 {
                    l.coeffs
                        .set(i, j, k, if j < 16 { 1.0 } else { 0.1 * (i - 8) as f32 });
                }
            }
        }
        let mut clay = Clay::single(l);
        let before = clay.clone();
        let mut rec = StepRecorder::new("open");
        rec.touch_all(&clay);
        let bricks = clay.base().coeffs.brick_count();
        assert_eq!(rec.old.len(), bricks);
        let each = rec
            .old
            .values()
            .filter(|saved| matches!(saved.bits, SavedBits::Each(_)))
            .count();
        assert_eq!(each, 1, "only the ramp's brick holds different values");
        // Other values in a solid brick, the ramp's and far away: one step, and undo brings
        // every bit back.
        clay.base_mut()
            .coeffs
            .write_box([8, 8, 8], [8, 16, 8], &[0.25; 1024]);
        clay.base_mut().coeffs.set(200, 100, 40, -1.0);
        let mut history = History::default();
        assert!(history.commit(rec, &clay));
        history.undo(&mut clay).unwrap();
        assert!(clay == before);
        history.redo(&mut clay).unwrap();
        assert_eq!(clay.base().coeffs.get(200, 100, 40), -1.0);
        assert_eq!(clay.base().coeffs.get(10, 20, 10), 0.25);
    }

    #[test]
    fn a_step_that_folds_a_patch_away_undoes_and_redoes_bit_for_bit_with_the_layout() {
        let mut clay = clay();
        let z = Vec3::new(0.0, 0.0, 0.3);
        for x in [0.5, 1.0] {
            let lo = Vec3::new(x, 0.4, 0.0) + z;
            clay.density
                .refine(lo, lo + Vec3::new(0.3, 0.2, 0.05), 1)
                .unwrap();
        }
        let start = clay.clone();
        let mut history = History::default();
        // A carve writes into both detail patches.
        let mut rec = StepRecorder::new("carve");
        for n in [1, 2] {
            let whole = CoeffBox::whole(clay.density.patches[n].lattice.dims);
            rec.touch(&clay, FieldId::Density(n as u16), whole);
            fill(&mut clay, n, |i| (i % 5) as f32 * 0.01 * n as f32);
        }
        assert!(history.commit(rec, &clay));
        let carved = clay.clone();
        // A smoothing wipes patch 1, changes patch 2, and the wiped patch is folded into the
        // base (whose box is rewritten); patch 2 moves to index 1 and is changed again.
        let mut rec = StepRecorder::new("smooth");
        let whole = CoeffBox::whole(clay.density.patches[1].lattice.dims);
        rec.touch(&clay, FieldId::Density(1), whole);
        fill(&mut clay, 1, |_| 0.0);
        let whole2 = CoeffBox::whole(clay.density.patches[2].lattice.dims);
        rec.touch(&clay, FieldId::Density(2), whole2);
        fill(&mut clay, 2, |i| (i % 3) as f32 * 0.02);
        let region = CoeffBox {
            min: [4, 3, 1],
            max: [9, 6, 3],
        };
        let plan = CoarsenPlan {
            patch: 1,
            into: 0,
            rewrite: Some((region, vec![0.25; region.count()])),
            displacement_fu: 0.0,
        };
        rec.coarsen(&mut clay, &plan).unwrap();
        assert_eq!(clay.density.patches.len(), 2);
        fill(&mut clay, 1, |i| (i % 4) as f32 * 0.03);
        assert!(history.commit(rec, &clay));
        let smoothed = clay.clone();

        history.undo(&mut clay).unwrap();
        assert_eq!(
            clay, carved,
            "undo puts the folded patch back as the smoothing found it"
        );
        history.undo(&mut clay).unwrap();
        assert_eq!(clay, start);
        history.redo(&mut clay).unwrap();
        assert_eq!(clay, carved);
        history.redo(&mut clay).unwrap();
        assert_eq!(clay, smoothed, "redo folds it away again");
        assert!(history.used_bytes() >= 4 * carved.density.patches[1].lattice.coeffs.len());
    }

    #[test]
    fn steps_before_and_a_stroke_across_a_growth_undo_and_redo_bit_for_bit_on_the_grown_clay() {
        let mut clay = clay();
        let mut history = History::default();
        let start = clay.clone();
        edit(
            &mut clay,
            &mut history,
            CoeffBox {
                min: [2, 2, 2],
                max: [9, 5, 4],
            },
            2.0,
        );
        let after_first = clay.clone();
        // A stroke touches a box, the clay grows under it, and the stroke goes on.
        let mut rec = StepRecorder::new("stroke");
        let early = CoeffBox {
            min: [10, 3, 1],
            max: [17, 8, 6],
        };
        rec.touch(&clay, FieldId::Density(0), early);
        let at = clay.base().index(12, 4, 3);
        clay.base_mut().coeffs.set_flat(at, -1.0);
        let growth = clay.grow([8, 0, 8]).unwrap();
        history.regrid(&growth);
        rec.regrid(&growth);
        let late = early.shifted(growth.pad);
        rec.touch(&clay, FieldId::Density(0), late);
        let at = clay
            .base()
            .index(late.min[0] + 5, late.min[1] + 2, late.min[2] + 1);
        clay.base_mut().coeffs.set_flat(at, 7.0);
        // Past the old far side, in a brick that was clipped there before the growth.
        let beyond = CoeffBox {
            min: [29, 4, 9],
            max: [30, 5, 10],
        };
        rec.touch(&clay, FieldId::Density(0), beyond);
        let at = clay.base().index(30, 5, 10);
        clay.base_mut().coeffs.set_flat(at, 5.0);
        history.commit(rec, &clay);
        let done = clay.clone();
        // Undo the stroke: the grown clay holds the first edit's coefficients again.
        history.undo(&mut clay).unwrap();
        let mut grown_first = after_first.clone();
        grown_first.grow([8, 0, 8]).unwrap();
        assert_eq!(clay.base().coeffs, grown_first.base().coeffs);
        history.undo(&mut clay).unwrap();
        let mut grown_start = start.clone();
        grown_start.grow([8, 0, 8]).unwrap();
        assert_eq!(clay.base().coeffs, grown_start.base().coeffs);
        history.redo(&mut clay).unwrap();
        history.redo(&mut clay).unwrap();
        assert_eq!(clay.base().coeffs, done.base().coeffs);
    }

    #[test]
    fn undo_then_redo_is_bit_exact_including_nan_payloads_and_negative_zero() {
        let mut c = clay();
        let before = c.clone();
        let mut h = History::default();
        let region = CoeffBox {
            min: [3, 2, 1],
            max: [16, 10, 7],
        };
        edit(&mut c, &mut h, region, -0.0);
        edit(&mut c, &mut h, region, f32::from_bits(0x7fc0_1234));
        let after = c.density.patches[0]
            .lattice
            .coeffs
            .iter()
            .map(|x| x.to_bits())
            .collect::<Vec<_>>();
        assert_eq!(h.undo(&mut c).unwrap().as_deref(), Some("set"));
        h.undo(&mut c).unwrap();
        let bits = |c: &Clay| {
            c.density.patches[0]
                .lattice
                .coeffs
                .iter()
                .map(|x| x.to_bits())
                .collect::<Vec<_>>()
        };
        assert_eq!(bits(&c), bits(&before));
        assert_eq!(h.undo(&mut c).unwrap(), None);
        h.redo(&mut c).unwrap();
        h.redo(&mut c).unwrap();
        assert_eq!(bits(&c), after);
        assert_eq!(h.redo(&mut c).unwrap(), None);
    }

    #[test]
    fn an_unchanged_region_records_nothing_and_a_new_step_clears_redo() {
        let mut c = clay();
        let mut h = History::default();
        let rec = {
            let mut r = StepRecorder::new("noop");
            r.touch(&c, FieldId::Density(0), CoeffBox::whole([20, 13, 9]));
            r
        };
        assert!(!h.commit(rec, &c));
        let region = CoeffBox {
            min: [0; 3],
            max: [1, 1, 1],
        };
        edit(&mut c, &mut h, region, 5.0);
        h.undo(&mut c).unwrap();
        assert_eq!(h.redo_len(), 1);
        edit(&mut c, &mut h, region, 6.0);
        assert_eq!(h.redo_len(), 0);
        assert_eq!(h.undo_len(), 1);
    }

    #[test]
    fn the_budget_drops_the_oldest_steps_first() {
        let mut c = clay();
        let region = CoeffBox {
            min: [0; 3],
            max: [7, 7, 7],
        };
        let one_step = {
            let mut probe = c.clone();
            let mut h = History::default();
            edit(&mut probe, &mut h, region, 9.0);
            h.used_bytes()
        };
        let mut h = History::new(3 * one_step);
        for v in 0..5 {
            edit(&mut c, &mut h, region, v as f32 + 10.0);
        }
        assert_eq!(h.undo_len(), 3);
        assert_eq!(h.dropped_steps(), 2);
        assert!(h.used_bytes() <= h.budget_bytes);
        h.undo(&mut c).unwrap();
        h.undo(&mut c).unwrap();
        h.undo(&mut c).unwrap();
        // Back to the state after the second edit (value 11), the oldest kept step's base.
        assert_eq!(c.density.patches[0].lattice.coeffs[0], 11.0);
    }

    #[test]
    fn a_step_for_a_resized_field_is_refused_and_changes_nothing() {
        let mut c = clay();
        let mut h = History::default();
        edit(
            &mut c,
            &mut h,
            CoeffBox {
                min: [0; 3],
                max: [3; 3],
            },
            1.0,
        );
        c.density.patches[0].lattice = BSplineLattice::zeros([5, 5, 5], 0.1, Vec3::ZERO).unwrap();
        let snapshot = c.clone();
        assert!(matches!(
            h.undo(&mut c),
            Err(HistoryError::FieldMismatch { .. })
        ));
        assert_eq!(c, snapshot);
        assert_eq!(h.undo_len(), 1);
    }
}

#[cfg(test)]
mod property {
    use glam::Vec3;
    use proptest::prelude::*;

    use super::*;
    use crate::field::BSplineLattice;
    use crate::tools::{
        ApplyOptions, ColourField, ContactParams, GeometricTool, StampParams, ToolAction, ToolPose,
        ToolShape, apply_tool,
    };

    #[derive(Clone, Debug)]
    enum Op {
        Tool {
            kind: u8,
            at: [f32; 3],
            size: f32,
            dt: f32,
        },
        Undo,
        Redo,
    }

    fn op() -> impl Strategy<Value = Op> {
        prop_oneof![
            6 => (0_u8..10, prop::array::uniform3(0.0_f32..1.0), 0.08_f32..0.25, 0.05_f32..1.0)
                .prop_map(|(kind, at, size, dt)| Op::Tool { kind, at, size, dt }),
            2 => Just(Op::Undo),
            1 => Just(Op::Redo),
        ]
    }

    fn bits(clay: &Clay) -> Vec<u32> {
        let mut out: Vec<u32> = clay
            .density
            .patches
            .iter()
            .flat_map(|p| p.lattice.coeffs.iter().map(|c| c.to_bits()))
            .collect();
        if let Some(c) = &clay.colour {
            for ch in &c.channels {
                out.extend(ch.coeffs.iter().map(|c| c.to_bits()));
            }
        }
        out
    }

    fn tool(kind: u8, size: f32) -> GeometricTool {
        let shape = match kind % 3 {
            0 => ToolShape::Sphere { radius_fu: size },
            1 => ToolShape::Box {
                half_extents_fu: Vec3::new(size, 0.7 * size, 0.5 * size),
            },
            _ => ToolShape::Capsule {
                radius_fu: 0.6 * size,
                half_height_fu: size,
            },
        };
        let action = match kind {
            0 | 1 => ToolAction::Add {
                deposit_rate_per_s: 2.0,
            },
            2 => ToolAction::Remove,
            3 => ToolAction::SoftRemove { rate_per_s: 1.0 },
            4 => ToolAction::Paint {
                rgb: [0.9, 0.1, 0.3],
            },
            5 => ToolAction::Smooth {
                rate_per_s: 1.0,
                kernel_fu: 0.08,
            },
            6 => ToolAction::Stamp(StampParams::default()),
            7 => ToolAction::Contact(ContactParams::with_alpha(-2.0)),
            8 => ToolAction::Union,
            _ => ToolAction::Difference,
        };
        GeometricTool {
            shape,
            action,
            falloff_fu: 0.1,
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 6, ..ProptestConfig::default() })]

        #[test]
        fn undo_and_redo_are_bit_exact_over_random_sequences(ops in prop::collection::vec(op(), 100)) {
            let lattice = BSplineLattice::zeros([14, 14, 14], 1.0 / 12.0, Vec3::ZERO).unwrap();
            let mut clay = Clay {
                colour: Some(ColourField::matching(&lattice).unwrap()),
                density: crate::field::MultiPatchField::new(lattice),
                constraints: Vec::new(),
                mask: None,
            };
            let mut history = History::default();
            let mut timeline = vec![bits(&clay)];
            let mut pos = 0;
            for op in ops {
                match op {
                    Op::Tool { kind, at, size, dt } => {
                        let t = tool(kind, size);
                        let mut rec = StepRecorder::new(t.action.name());
                        let pose = ToolPose::at(Vec3::from_array(at) * 1.1);
                        apply_tool(&mut clay, &t, &pose, dt, &ApplyOptions::default(), Some(&mut rec)).unwrap();
                        if history.commit(rec, &clay) {
                            timeline.truncate(pos + 1);
                            timeline.push(bits(&clay));
                            pos += 1;
                        } else {
                            prop_assert_eq!(&bits(&clay), &timeline[pos]);
                        }
                    }
                    Op::Undo => {
                        let undone = history.undo(&mut clay).unwrap();
                        prop_assert_eq!(undone.is_some(), pos > 0);
                        pos = pos.saturating_sub(1);
                        prop_assert!(bits(&clay) == timeline[pos], "undo not bit-exact");
                    }
                    Op::Redo => {
                        let redone = history.redo(&mut clay).unwrap();
                        prop_assert_eq!(redone.is_some(), pos + 1 < timeline.len());
                        if redone.is_some() {
                            pos += 1;
                        }
                        prop_assert!(bits(&clay) == timeline[pos], "redo not bit-exact");
                    }
                }
            }
            // Unwind everything: back to the empty clay.
            while history.undo(&mut clay).unwrap().is_some() {}
            prop_assert!(bits(&clay) == timeline[0]);
        }
    }
}
