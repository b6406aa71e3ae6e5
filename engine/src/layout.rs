//! A new patch layout for the loops' field copies: when the clay gains a detail patch ("refine
//! here"), the haptic and graphics loops need copies laid out like the simulation's field. The
//! simulation builds each copy (it may allocate) and hands it over; the reader swaps it in and
//! hands its old copy back to be dropped on the simulation thread.
//!
//! Guarantee: the reader's side ([`LayoutPort::install`], [`LayoutPort::take_spare`],
//! [`LayoutPort::take_spare_group`]) is wait-free and allocation-free: it uses crossbeam array
//! channels (two of capacity one for the copies, two of [`HAPTIC_SPARE_BRICKS`] for the spare
//! bricks and the spare group entries), only through `try_recv` and `try_send`, and moves
//! boxes by pointer, so no memory is allocated or freed on the haptic thread. The copy goes back only while the return slot has room; otherwise the
//! handover waits.
//!
//! The copies are as sparse as the simulation's field: a uniform brick stays one value (see
//! [`dynaclay_core::field::BrickedCoeffs`]). A reader that must not allocate (the haptic loop)
//! is given a channel with spare bricks ([`layout_channel_with_spares`]): before it writes an
//! update, [`super::FieldUpdate::densify_for_copy`] makes dense, from this pool, the uniform
//! bricks the update's values would make dense (and gives their groups entries, from the
//! pool's spare groups, where a group of the copy was one value); the write then allocates
//! nothing. The
//! simulation keeps the pool full ([`LayoutSender::drop_retired`], every publication), so the
//! bricks live in the copy only where the clay holds detail, and the pool's capacity bounds
//! the work one tick spends on it. An update needing more bricks than the pool holds waits, a
//! tick at a time, with the bricks already taken kept dense (that changes no value) until the
//! pool, refilled, covers it; the reader neither applies nor acknowledges it meanwhile, so
//! the simulation keeps publishing every change since (see [`super::FieldUpdate`]). A copy
//! never frees a brick it made dense (the haptic thread frees nothing); the simulation offers
//! a fresh copy before the bricks it published since the last one could take a copy past the
//! clay's dense-brick budget ([`dynaclay_core::field::MAX_DENSE_BRICKS`]), and instead of
//! boxes of more than [`super::MAX_UPDATE_COEFFS`] coefficients.
//!
//! Every [`super::FieldUpdate`] names the layout generation its boxes belong to; a reader
//! whose copy has another generation neither applies nor acknowledges it, so the simulation
//! keeps publishing every change since the new layout until both readers hold it.

use crossbeam::channel::{Receiver, Sender, bounded};

use dynaclay_core::field::{
    DENSE_BRICK_BYTES, MultiPatchField, SPARE_GROUP_BYTES, SpareBrick, SpareGroup, SpareStorage,
};

/// Spare dense bricks waiting for the haptic loop (1.3 MiB at [`DENSE_BRICK_BYTES`] each): an
/// update whose values make at most this many of its copy's uniform bricks dense is applied
/// in the tick it arrives (a stroke's publication makes a few dense at a time: the bricks its
/// edit reached for the first time since the previous one), and this is the most bricks one
/// tick fills (256 × 1 331 values).
pub const HAPTIC_SPARE_BRICKS: usize = 256;

/// Bytes the haptic loop's pool of spare bricks and spare groups holds when full (as many
/// groups as bricks: a brick made dense needs at most its group's entries besides).
pub const HAPTIC_SPARE_BYTES: usize = HAPTIC_SPARE_BRICKS * (DENSE_BRICK_BYTES + SPARE_GROUP_BYTES);

/// A copy of the simulation's field in its new layout.
#[derive(Debug)]
pub struct LayoutHandover {
    /// The layout's generation (0 is the layout the engine started with).
    pub generation: u64,
    /// The copy, boxed so that it moves into the reader by pointer.
    pub field: Box<MultiPatchField>,
}

/// A reader's end.
#[derive(Debug)]
pub struct LayoutPort {
    incoming: Receiver<LayoutHandover>,
    retired: Sender<Box<MultiPatchField>>,
    /// Spare dense bricks and group entries for writes into the copy (none for a reader
    /// that may allocate).
    spares: Option<(Receiver<SpareBrick>, Receiver<SpareGroup>)>,
}

impl LayoutPort {
    /// A spare dense brick from the pool the simulation fills, if one waits (never for a
    /// port made without spares). Wait-free, allocation-free.
    #[must_use]
    pub fn take_spare(&self) -> Option<SpareBrick> {
        self.spares.as_ref()?.0.try_recv().ok()
    }

    /// A spare group's entries from the pool the simulation fills, if one waits (never for a
    /// port made without spares). Wait-free, allocation-free.
    #[must_use]
    pub fn take_spare_group(&self) -> Option<SpareGroup> {
        self.spares.as_ref()?.1.try_recv().ok()
    }

    /// Swaps a waiting layout into `field` and returns its generation, sending the old copy
    /// back to the simulation. Does nothing (and returns `None`) when no layout waits or when
    /// the return slot is still full.
    pub fn install(&self, field: &mut Box<MultiPatchField>) -> Option<u64> {
        self.install_inspecting(field, |_, _| {})
    }

    /// As [`LayoutPort::install`], and before the old copy goes back, calls `inspect` with it
    /// and the new one (for a reader that compares them, off the haptic thread: the graphics
    /// loop finds what changed besides the layout).
    pub fn install_inspecting(
        &self,
        field: &mut Box<MultiPatchField>,
        inspect: impl FnOnce(&MultiPatchField, &MultiPatchField),
    ) -> Option<u64> {
        if self.retired.is_full() {
            return None;
        }
        let handover = self.incoming.try_recv().ok()?;
        let old = std::mem::replace(field, handover.field);
        inspect(&old, field);
        // The slot had room and this port is its only sender; if the simulation is gone the
        // copy comes back and is dropped here, at shutdown only.
        let _ = self.retired.try_send(old);
        Some(handover.generation)
    }
}

/// The pool behind a reader's end, for [`dynaclay_core::field::BrickedCoeffs::densify_for_box`]:
/// wait-free, allocation-free.
impl SpareStorage for &LayoutPort {
    fn spare_brick(&mut self) -> Option<SpareBrick> {
        self.take_spare()
    }
    fn spare_group(&mut self) -> Option<SpareGroup> {
        self.take_spare_group()
    }
}

/// The simulation's end.
#[derive(Debug)]
pub struct LayoutSender {
    incoming: Sender<LayoutHandover>,
    /// A second receiver on the incoming slot, to replace a layout the reader never took.
    withdraw: Receiver<LayoutHandover>,
    retired: Receiver<Box<MultiPatchField>>,
    /// Where spare dense bricks and group entries go to the reader (see the module
    /// documentation).
    spares: Option<(Sender<SpareBrick>, Sender<SpareGroup>)>,
}

impl LayoutSender {
    /// Offers a copy of `field` in layout `generation`, replacing an older offer the reader
    /// has not taken yet, and drops the copies readers have handed back. The copy is as
    /// sparse as `field`.
    pub fn offer(&self, field: &MultiPatchField, generation: u64) {
        self.drop_retired();
        while self.withdraw.try_recv().is_ok() {}
        // The slot was just emptied and this is its only sender: the send succeeds unless the
        // reader is gone, when there is nobody left to offer to.
        let _ = self.incoming.try_send(LayoutHandover {
            generation,
            field: Box::new(field.clone()),
        });
    }

    /// Drops the copies readers have handed back and tops the pool of spare bricks up to its
    /// capacity, allocating the bricks here (the simulation calls this every publication).
    pub fn drop_retired(&self) {
        while self.retired.try_recv().is_ok() {}
        if let Some((bricks, groups)) = &self.spares {
            // Fails only when the pool is full, or when the reader is gone (nobody to fill
            // for); this is the pool's only sender, so the room seen cannot shrink meanwhile.
            while !bricks.is_full() && bricks.try_send(SpareBrick::new()).is_ok() {}
            while !groups.is_full() && groups.try_send(SpareGroup::new()).is_ok() {}
        }
    }
}

/// A connected pair of ends, for a reader that may allocate when it writes into its copy
/// (the graphics loop).
#[must_use]
pub fn layout_channel() -> (LayoutSender, LayoutPort) {
    connected(None)
}

/// A connected pair of ends whose reader also gets a pool of `capacity` spare dense bricks
/// and as many spare group entries, filled at once and topped up at every [`LayoutSender::drop_retired`], so that it writes
/// into its sparse copy without allocating (the haptic loop, with [`HAPTIC_SPARE_BRICKS`]).
///
/// # Panics
/// When `capacity` is zero.
#[must_use]
pub fn layout_channel_with_spares(capacity: usize) -> (LayoutSender, LayoutPort) {
    assert!(capacity > 0, "a pool of spare bricks holds at least one");
    let (bricks_tx, bricks_rx) = bounded(capacity);
    let (groups_tx, groups_rx) = bounded(capacity);
    let (sender, port) = connected(Some(((bricks_tx, groups_tx), (bricks_rx, groups_rx))));
    sender.drop_retired();
    (sender, port)
}

/// The ends of a pool of spares: what the simulation sends, what the reader receives.
type SparePool = (
    (Sender<SpareBrick>, Sender<SpareGroup>),
    (Receiver<SpareBrick>, Receiver<SpareGroup>),
);

fn connected(spares: Option<SparePool>) -> (LayoutSender, LayoutPort) {
    let (in_tx, in_rx) = bounded(1);
    let (out_tx, out_rx) = bounded(1);
    let (spares_tx, spares_rx) = spares.unzip();
    (
        LayoutSender {
            incoming: in_tx,
            withdraw: in_rx.clone(),
            retired: out_rx,
            spares: spares_tx,
        },
        LayoutPort {
            incoming: in_rx,
            retired: out_tx,
            spares: spares_rx,
        },
    )
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use dynaclay_core::field::BSplineLattice;

    fn field(n: usize) -> MultiPatchField {
        let mut f = MultiPatchField::new(BSplineLattice::zeros([4; 3], 1.0, Vec3::ZERO).unwrap());
        for _ in 1..n {
            f.add_detail(Vec3::ONE, Vec3::splat(2.0), 1).unwrap();
        }
        f
    }

    #[test]
    fn a_newer_offer_replaces_an_untaken_one_and_old_copies_come_back() {
        let (sender, port) = layout_channel();
        let mut copy = Box::new(field(1));
        assert_eq!(port.install(&mut copy), None, "nothing offered");
        sender.offer(&field(2), 1);
        sender.offer(&field(3), 2);
        assert_eq!(port.install(&mut copy), Some(2), "the newest offer");
        assert_eq!(copy.patches.len(), 3);
        assert_eq!(port.install(&mut copy), None);
        // The old copy waits in the return slot; a further layout is installed only once the
        // simulation has taken it back.
        sender
            .incoming
            .try_send(LayoutHandover {
                generation: 3,
                field: Box::new(field(4)),
            })
            .unwrap();
        assert_eq!(port.install(&mut copy), None, "return slot full");
        sender.drop_retired();
        assert_eq!(port.install(&mut copy), Some(3));
        assert_eq!(copy.patches.len(), 4);
    }

    #[test]
    fn offered_copies_stay_sparse_and_the_pool_is_topped_up_at_each_drop() {
        let (sender, port) = layout_channel_with_spares(3);
        let mut copy = Box::new(field(1));
        sender.offer(&field(2), 1);
        assert_eq!(port.install(&mut copy), Some(1));
        let dense: usize = copy
            .patches
            .iter()
            .map(|p| p.lattice.coeffs.dense_brick_count())
            .sum();
        assert_eq!(dense, 0, "a copy of an all-zero field holds no dense brick");
        let taken: Vec<_> = std::iter::from_fn(|| port.take_spare()).collect();
        assert_eq!(taken.len(), 3, "filled when made");
        assert!(port.take_spare().is_none());
        let groups: Vec<_> = std::iter::from_fn(|| port.take_spare_group()).collect();
        assert_eq!(groups.len(), 3, "as many groups, filled when made");
        sender.drop_retired();
        assert_eq!(std::iter::from_fn(|| port.take_spare()).count(), 3);
        let mut pool = &port;
        assert!(pool.spare_group().is_some(), "the port is a pool of spares");
        assert_eq!(std::iter::from_fn(|| pool.spare_group()).count(), 2);
        let (_, plain) = layout_channel();
        assert!(plain.take_spare().is_none(), "the graphics end has no pool");
        assert!(plain.take_spare_group().is_none());
    }
}
