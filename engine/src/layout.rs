//! A new patch layout for the loops' field copies: when the clay gains a detail patch ("refine
//! here"), the haptic and graphics loops need copies laid out like the simulation's field. The
//! simulation builds each copy (it may allocate) and hands it over; the reader swaps it in and
//! hands its old copy back to be dropped on the simulation thread.
//!
//! Guarantee: the reader's side ([`LayoutPort::install`]) is wait-free and allocation-free: it
//! uses two crossbeam array channels of capacity one, only through `try_recv` and `try_send`,
//! and moves boxes by pointer, so no memory is allocated or freed on the haptic thread. The
//! copy goes back only while the return slot has room; otherwise the handover waits.
//!
//! Every [`super::FieldUpdate`] names the layout generation its boxes belong to; a reader
//! whose copy has another generation neither applies nor acknowledges it, so the simulation
//! keeps publishing every change since the new layout until both readers hold it.

use crossbeam::channel::{Receiver, Sender, bounded};

use dynaclay_core::field::MultiPatchField;

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
}

impl LayoutPort {
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

/// The simulation's end.
#[derive(Debug)]
pub struct LayoutSender {
    incoming: Sender<LayoutHandover>,
    /// A second receiver on the incoming slot, to replace a layout the reader never took.
    withdraw: Receiver<LayoutHandover>,
    retired: Receiver<Box<MultiPatchField>>,
    /// Whether the copies offered have every brick dense (for a reader that writes into its
    /// copy on a thread that must not allocate).
    dense_copies: bool,
}

impl LayoutSender {
    /// This sender, offering copies whose bricks are all dense, so that the reader's writes
    /// into them never allocate (the haptic loop's).
    #[must_use]
    pub fn with_dense_copies(mut self) -> Self {
        self.dense_copies = true;
        self
    }

    /// Offers a copy of `field` in layout `generation`, replacing an older offer the reader
    /// has not taken yet, and drops the copies readers have handed back.
    pub fn offer(&self, field: &MultiPatchField, generation: u64) {
        self.drop_retired();
        while self.withdraw.try_recv().is_ok() {}
        // The slot was just emptied and this is its only sender: the send succeeds unless the
        // reader is gone, when there is nobody left to offer to.
        let mut copy = Box::new(field.clone());
        if self.dense_copies {
            copy.densify_all();
        }
        let _ = self.incoming.try_send(LayoutHandover {
            generation,
            field: copy,
        });
    }

    /// Drops the copies readers have handed back (the simulation calls this every step).
    pub fn drop_retired(&self) {
        while self.retired.try_recv().is_ok() {}
    }
}

/// A connected pair of ends.
#[must_use]
pub fn layout_channel() -> (LayoutSender, LayoutPort) {
    let (in_tx, in_rx) = bounded(1);
    let (out_tx, out_rx) = bounded(1);
    (
        LayoutSender {
            incoming: in_tx,
            withdraw: in_rx.clone(),
            retired: out_rx,
            dense_copies: false,
        },
        LayoutPort {
            incoming: in_rx,
            retired: out_tx,
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
}
