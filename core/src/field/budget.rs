//! The clay's memory budget: dense bricks, not boxes.
//!
//! A clay's coefficients are stored in bricks ([`BrickedCoeffs`]): a brick that holds one
//! value (empty space, solid interior) costs only its directory entry
//! ([`BrickedCoeffs::DIRECTORY_BYTES_PER_BRICK`] bytes per [`COEFF_BRICK_VALUES`]
//! coefficients of the box), a dense one [`DENSE_BRICK_BYTES`] on the heap. So two budgets
//! bound a clay, all its density patches, colour channels and freeze mask together:
//!
//! - [`MAX_DENSE_BRICKS`] dense bricks ([`DENSE_BRICK_BUDGET_BYTES`]): the memory the clay's
//!   surface and simulated regions cost. Every write that can make bricks dense is checked
//!   against it *before* it changes anything, with the uniform bricks its coefficient box
//!   reaches as the bound of what it can make dense
//!   ([`BrickedCoeffs::uniform_bricks_holding`]): a tool's application, a simulated region, a
//!   growth, a session load (brick by brick, before each dense brick is allocated) and an
//!   import. A write past it is refused with a [`DenseBudgetError`] and the clay is left as
//!   it was. The count is kept as bricks change ([`BrickedCoeffs::dense_brick_count`] walks
//!   nothing), so a check costs one directory read per brick the edit's box reaches.
//! - [`MAX_CLAY_BOX_COEFFS`] coefficients of box: what the directories cost, at most
//!   [`MAX_DIRECTORY_BYTES`] per copy of the clay. A refine, a growth and a session load are
//!   checked against it before anything is allocated, so a hostile session file or script
//!   cannot make an absurd directory.
//!
//! Because an admitted write's box holds at most [`MAX_DENSE_BRICKS`] bricks (its uniform
//! bricks and the clay's dense ones fit the budget together), the scratch an edit fills over
//! its box is bounded by the same budget. A clay that saves always loads: loading applies the
//! same count to the same bricks, and never holds more dense bricks than the clay saved.

use super::bricks::{BrickedCoeffs, COEFF_BRICK_VALUES, DENSE_BRICK_BYTES};
use super::mass_grid::CoeffBox;

/// Heap bytes the dense bricks of one copy of a clay may take: 768 MiB (the old box budget
/// of 64 Mi coefficients, every brick dense, fits it).
pub const DENSE_BRICK_BUDGET_BYTES: usize = 768 << 20;

/// Most dense bricks one clay may hold, every density patch, colour channel and mask
/// together: [`DENSE_BRICK_BUDGET_BYTES`] over [`DENSE_BRICK_BYTES`] (151 259 bricks, about
/// 77 Mi coefficients with their aprons).
pub const MAX_DENSE_BRICKS: usize = DENSE_BRICK_BUDGET_BYTES / DENSE_BRICK_BYTES;

/// Most coefficients of box a clay may span, all its lattices together (1 Gi: a base of
/// 1024³, or one of 4096 × 512 × 512): what its brick directories may cost, not its dense
/// bricks. At [`BrickedCoeffs::DIRECTORY_BYTES_PER_BRICK`] bytes per brick of
/// [`COEFF_BRICK_VALUES`] coefficients that is [`MAX_DIRECTORY_BYTES`] per copy.
pub const MAX_CLAY_BOX_COEFFS: usize = 1 << 30;

/// Bytes the brick directories of a clay at [`MAX_CLAY_BOX_COEFFS`] take, per copy (32 MiB).
pub const MAX_DIRECTORY_BYTES: usize =
    MAX_CLAY_BOX_COEFFS / COEFF_BRICK_VALUES * BrickedCoeffs::DIRECTORY_BYTES_PER_BRICK;

// The old box budget of 64 Mi coefficients, every brick dense, fits the dense budget: no clay
// that loaded before is refused for its dense bricks.
const _: () = assert!(MAX_DENSE_BRICKS >= (64 << 20) / COEFF_BRICK_VALUES);

/// A write that could make the clay hold more than [`MAX_DENSE_BRICKS`] dense bricks; the
/// clay was left unchanged.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "{} could make {more} more bricks dense where the clay holds {dense}; a clay holds at most {MAX_DENSE_BRICKS} dense bricks ({} MiB), so it was refused and nothing changed",
    place(.at),
    DENSE_BRICK_BUDGET_BYTES >> 20
)]
pub struct DenseBudgetError {
    /// Dense bricks the clay holds.
    pub dense: usize,
    /// Bricks the write could make dense (the uniform ones its box reaches).
    pub more: usize,
    /// The coefficient box of the lattice written, when the write has one.
    pub at: Option<CoeffBox>,
}

/// Where a refused write was, in words.
fn place(at: &Option<CoeffBox>) -> String {
    match at {
        Some(b) => format!("an edit of coefficients {:?}..={:?}", b.min, b.max),
        None => "the clay".to_owned(),
    }
}

/// Whether `more` bricks made dense fit beside the `dense` a clay holds.
///
/// # Errors
/// [`DenseBudgetError`] when together they exceed [`MAX_DENSE_BRICKS`].
pub fn check_dense_room(
    dense: usize,
    more: usize,
    at: Option<CoeffBox>,
) -> Result<(), DenseBudgetError> {
    if dense.saturating_add(more) > MAX_DENSE_BRICKS {
        Err(DenseBudgetError { dense, more, at })
    } else {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_budgets_mean_what_their_names_say() {
        assert_eq!(MAX_DENSE_BRICKS, 151_259);
        assert_eq!(BrickedCoeffs::DIRECTORY_BYTES_PER_BRICK, 16);
        assert_eq!(MAX_DIRECTORY_BYTES, 32 << 20);
    }

    #[test]
    fn room_is_refused_past_the_budget_and_says_where() {
        assert_eq!(check_dense_room(MAX_DENSE_BRICKS - 5, 5, None), Ok(()));
        let at = CoeffBox {
            min: [1, 2, 3],
            max: [40, 50, 60],
        };
        let err = check_dense_room(MAX_DENSE_BRICKS - 5, 6, Some(at)).unwrap_err();
        assert_eq!(err.more, 6);
        let text = err.to_string();
        assert!(
            text.contains("[1, 2, 3]..=[40, 50, 60]") && text.contains("768 MiB"),
            "{text}"
        );
        assert!(check_dense_room(usize::MAX, 1, None).is_err());
    }
}
