//! Pinning, the tool of Hua & Qin §7.3: pins as the user asks for them (script steps, the GUI): a point, a curve or a normal at
//! places that may be off the surface, turned into the clay's [`Constraint`]s, and the
//! constraint stage of a dynamics region built from the clay's pins.
//!
//! "Pin" means what a CAD user expects: the place stays where it is on the surface while the
//! clay around it is pushed and pulled. A point not on the surface is first moved onto it
//! (along the field's gradient, at most [`PROJECT_REACH_SPANS`] knot spans) and the outcome
//! says so. Runs on the simulation thread between steps; it allocates.

use glam::Vec3;

use super::clay::{Clay, CoeffBox};
use crate::dynamics::ConstraintError;
use crate::dynamics::{
    Constraint, ConstraintPath, ConstraintReport, ConstraintRow, ConstraintSolver, MAX_CONSTRAINTS,
    RegionState, project_onto_surface,
};
use crate::field::MultiPatchField;

/// How far a point may be moved onto the surface, in knot spans.
pub const PROJECT_REACH_SPANS: f32 = 4.0;
/// A point this close to the surface (in field units) counts as on it.
pub const ON_SURFACE_TOLERANCE: f32 = 1e-5;

/// A pin as asked for, before its points are moved onto the surface.
#[derive(Clone, Debug, PartialEq)]
pub enum PinRequest {
    /// Keep this point on the surface.
    Point(Vec3),
    /// Keep the surface passing through this polyline.
    Curve(Vec<Vec3>),
    /// Keep the surface's normal at this point (the point is kept too: a pinned normal
    /// without its point would hold a direction in empty space once the surface moved).
    Normal(Vec3),
}

/// Why a pin could not be made or removed (nothing changes then).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PinError {
    /// The point (or, for a curve, `points[index]`) cannot be pinned.
    #[error("{}{source}", point.map(|i| format!("points[{i}]: ")).unwrap_or_default())]
    Point {
        /// Which vertex of a curve (`None` for a point or normal pin).
        point: Option<usize>,
        /// What is wrong with it.
        source: ConstraintError,
    },
    /// The clay has no density patch to pin.
    #[error("the clay has no patch to pin")]
    NoPatch,
    /// The clay's list of pins is full.
    #[error("the clay holds {existing} constraints; at most {limit} are allowed")]
    Full {
        /// Pins already on the clay.
        existing: usize,
        /// The bound.
        limit: usize,
    },
    /// `unconstrain` named a pin that does not exist.
    #[error("index = {index}: the clay has {count} constraint(s){}", if *count > 0 { format!(" (0 to {})", count - 1) } else { String::new() })]
    NoSuchPin {
        /// The index asked for.
        index: usize,
        /// Pins on the clay.
        count: usize,
    },
}

fn at_point(point: Option<usize>) -> impl Fn(ConstraintError) -> PinError {
    move |source| PinError::Point { point, source }
}

/// Moves `at` onto the clay's surface (of the sum of its patches); returns the point and how
/// far it moved.
fn onto_surface(field: &MultiPatchField, at: Vec3) -> Result<(Vec3, f32), ConstraintError> {
    let reach = PROJECT_REACH_SPANS * field.base().spacing;
    let on = project_onto_surface(field, at, reach)?;
    Ok((on, (on - at).length()))
}

/// Whether `at` lies off the clay's surface.
fn is_off_surface(field: &MultiPatchField, at: Vec3) -> bool {
    (field.value(at) - field.iso()).abs() > ON_SURFACE_TOLERANCE
}

fn moved_note(notes: &mut Vec<String>, at: Vec3, on: Vec3, by: f32, field: &MultiPatchField) {
    if is_off_surface(field, at) {
        notes.push(format!(
            "[{:.4}, {:.4}, {:.4}] was off the surface; projected {by:.4} onto it at [{:.4}, {:.4}, {:.4}]",
            at.x, at.y, at.z, on.x, on.y, on.z
        ));
    }
}

/// The constraints `request` stands for on the clay `field`, and a message saying what was pinned
/// (and which points were moved onto the surface first).
///
/// # Errors
/// [`PinError::Point`] naming the point when it is not finite, outside the clay, or has no
/// surface within reach, or when a curve has fewer than 2 points or too many samples.
pub fn resolve_pin(
    field: &MultiPatchField,
    request: &PinRequest,
) -> Result<(Vec<Constraint>, String), PinError> {
    let mut notes = Vec::new();
    let pins = match request {
        PinRequest::Point(at) => {
            let (on, by) = onto_surface(field, *at).map_err(at_point(None))?;
            moved_note(&mut notes, *at, on, by, field);
            vec![Constraint::Point { at: on }]
        }
        PinRequest::Normal(at) => {
            let (on, by) = onto_surface(field, *at).map_err(at_point(None))?;
            moved_note(&mut notes, *at, on, by, field);
            let normal = Constraint::normal_here(field, on).map_err(at_point(None))?;
            vec![normal, Constraint::Point { at: on }]
        }
        PinRequest::Curve(points) => {
            if points.len() < 2 {
                return Err(PinError::Point {
                    point: None,
                    source: ConstraintError::TooFewPoints { got: points.len() },
                });
            }
            let mut on_curve = Vec::with_capacity(points.len());
            let mut moved = 0;
            let mut furthest = 0.0_f32;
            for (i, &p) in points.iter().enumerate() {
                let (on, by) = onto_surface(field, p).map_err(at_point(Some(i)))?;
                if is_off_surface(field, p) {
                    moved += 1;
                    furthest = furthest.max(by);
                }
                on_curve.push(on);
            }
            if moved > 0 {
                notes.push(format!(
                    "{moved} of {} points were off the surface; projected onto it (at most {furthest:.4})",
                    points.len()
                ));
            }
            let curve = Constraint::Curve { points: on_curve };
            // Checks the sample count and that every sample lies in the clay.
            curve.rows_on_patch(field, 0).map_err(at_point(None))?;
            vec![curve]
        }
    };
    let what = match request {
        PinRequest::Point(_) => "pinned a point".to_owned(),
        PinRequest::Normal(_) => "pinned a normal and its point".to_owned(),
        PinRequest::Curve(p) => format!("pinned a curve of {} points", p.len()),
    };
    let message = if notes.is_empty() {
        what
    } else {
        format!("{what}; {}", notes.join("; "))
    };
    Ok((pins, message))
}

/// Pins `request` on `clay` (on the surface of the sum of its patches); returns what was
/// pinned with the new pins listed. The caller records the undo step
/// (`StepRecorder::touch_constraints` first).
///
/// # Errors
/// As [`resolve_pin`]; [`PinError::NoPatch`], or [`PinError::Full`] when the clay's list is
/// full.
pub fn add_pins(clay: &mut Clay, request: &PinRequest) -> Result<String, PinError> {
    if clay.density.patches.is_empty() {
        return Err(PinError::NoPatch);
    }
    let (pins, message) = resolve_pin(&clay.density, request)?;
    check_room(clay.constraints.len(), pins.len())?;
    let first = clay.constraints.len();
    clay.constraints.extend(pins);
    let listed: Vec<String> = (first..clay.constraints.len())
        .map(|i| describe_pin(i, &clay.constraints[i]))
        .collect();
    let check = describe_report(&check_pins(&clay.density, &clay.constraints));
    Ok(format!("{message} ({}); {check}", listed.join("; ")))
}

/// How well every pin of `pins` can be held together on the clay `field`'s base patch (rank
/// and residual of all their rows over the whole base lattice, the detail patches fixed).
#[must_use]
pub fn check_pins(field: &MultiPatchField, pins: &[Constraint]) -> ConstraintReport {
    let lattice = field.base();
    let rows: Vec<ConstraintRow> = pins
        .iter()
        .filter_map(|p| p.rows_on_patch(field, 0).ok())
        .flatten()
        .collect();
    ConstraintSolver::on_box(
        &rows,
        lattice,
        CoeffBox::whole(lattice.dims),
        &lattice.coeffs.to_vec(),
        ConstraintPath::Auto,
    )
    .report()
}

/// A report in words: rows and rank, and whether rows repeat or conflict.
#[must_use]
pub fn describe_report(r: &ConstraintReport) -> String {
    let mut s = format!("{} constraint rows, rank {}", r.rows, r.rank);
    if r.redundant() {
        s.push_str(&format!(" ({} redundant)", r.rows - r.rank));
    }
    if r.conflicting() {
        s.push_str(&format!(
            "; the pins conflict (residual {:.2e}): they are met as nearly as they can be",
            r.residual
        ));
    }
    s
}

/// Removes pin `index` from `clay`, or every pin with `None`; returns what was removed. The
/// caller records the undo step.
///
/// # Errors
/// [`PinError::NoSuchPin`] when `index` is past the end of the list (nothing changes then).
pub fn remove_pins(clay: &mut Clay, index: Option<usize>) -> Result<String, PinError> {
    let count = clay.constraints.len();
    match index {
        Some(i) if i >= count => Err(PinError::NoSuchPin { index: i, count }),
        Some(i) => Ok(format!(
            "removed {}",
            describe_pin(i, &clay.constraints.remove(i))
        )),
        None => {
            clay.constraints.clear();
            Ok(format!("removed all {count} constraint(s)"))
        }
    }
}

/// Whether `count` more pins fit beside `existing`.
///
/// # Errors
/// [`PinError::Full`] when they do not.
pub fn check_room(existing: usize, count: usize) -> Result<(), PinError> {
    if existing + count > MAX_CONSTRAINTS {
        return Err(PinError::Full {
            existing,
            limit: MAX_CONSTRAINTS,
        });
    }
    Ok(())
}

/// The constraint stage for `region`, a region of patch `patch` of the clay `field`, from
/// `pins` (each holding the sum of the patches, see [`Constraint::rows_on_patch`]). Pins that
/// make no rows (a point outside the clay) are left out and counted in the second value.
#[must_use]
pub fn solver_for(
    pins: &[Constraint],
    field: &MultiPatchField,
    patch: usize,
    region: &RegionState,
) -> (ConstraintSolver, usize) {
    let Some(lattice) = field.patches.get(patch).map(|p| &p.lattice) else {
        return (ConstraintSolver::empty(), pins.len());
    };
    if pins.is_empty() {
        return (ConstraintSolver::empty(), 0);
    }
    let mut rows: Vec<ConstraintRow> = Vec::new();
    let mut skipped = 0;
    for pin in pins {
        match pin.rows_on_patch(field, patch) {
            Ok(r) => rows.extend(r),
            Err(_) => skipped += 1,
        }
    }
    (
        ConstraintSolver::new(&rows, lattice, region, ConstraintPath::Auto),
        skipped,
    )
}

/// One line describing a pin, for lists (`0: point at [x, y, z]`).
#[must_use]
pub fn describe_pin(index: usize, pin: &Constraint) -> String {
    let v = |p: &Vec3| format!("[{:.3}, {:.3}, {:.3}]", p.x, p.y, p.z);
    match pin {
        Constraint::Point { at } => format!("{index}: point at {}", v(at)),
        Constraint::Normal { at, normal } => {
            format!("{index}: normal {} at {}", v(normal), v(at))
        }
        Constraint::Curve { points } => match (points.first(), points.last()) {
            (Some(a), Some(b)) => format!(
                "{index}: curve of {} points from {} to {}",
                points.len(),
                v(a),
                v(b)
            ),
            _ => format!("{index}: empty curve"),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::{Primitive, lattice_from_primitive};

    fn ball() -> Clay {
        let s = Primitive::Sphere {
            centre: Vec3::splat(0.95),
            radius: 0.4,
        };
        Clay::single(lattice_from_primitive([20; 3], 0.1, Vec3::ZERO, &s, 0.2, 2).unwrap())
    }

    #[test]
    fn pinning_says_what_it_moved_and_reports_redundant_pins() {
        let mut clay = ball();
        let first = add_pins(&mut clay, &PinRequest::Point(Vec3::new(1.5, 0.95, 0.95))).unwrap();
        assert!(first.contains("off the surface"), "{first}");
        assert!(first.contains("1 constraint rows, rank 1"), "{first}");
        let Constraint::Point { at } = clay.constraints[0] else {
            panic!("{:?}", clay.constraints)
        };
        // The same place again: its row repeats the first.
        let again = add_pins(&mut clay, &PinRequest::Point(at)).unwrap();
        assert!(!again.contains("off the surface"), "{again}");
        assert!(again.contains("rank 1 (1 redundant)"), "{again}");
        assert!(!again.contains("conflict"), "{again}");
        // A normal adds two rows and its point (a third, repeating the first two pins).
        let normal = add_pins(&mut clay, &PinRequest::Normal(at)).unwrap();
        assert!(normal.contains("5 constraint rows, rank 3"), "{normal}");
        assert_eq!(clay.constraints.len(), 4);
        assert!(
            remove_pins(&mut clay, Some(4))
                .unwrap_err()
                .to_string()
                .contains("0 to 3")
        );
        assert!(
            remove_pins(&mut clay, Some(1))
                .unwrap()
                .contains("removed 1: point")
        );
        assert!(remove_pins(&mut clay, None).unwrap().contains("all 3"));
        assert!(clay.constraints.is_empty());
    }

    #[test]
    fn a_pin_far_from_the_surface_or_outside_the_clay_is_refused_by_name() {
        // The centre of a ball of radius 0.7 is 7 knot spans deep: well beyond the reach of
        // 4 (the test ball's centre, 4 spans deep, sits on the reach itself).
        let big = Primitive::Sphere {
            centre: Vec3::splat(0.95),
            radius: 0.7,
        };
        let mut deep_clay =
            Clay::single(lattice_from_primitive([20; 3], 0.1, Vec3::ZERO, &big, 0.2, 2).unwrap());
        let deep = add_pins(&mut deep_clay, &PinRequest::Point(Vec3::splat(0.95)))
            .unwrap_err()
            .to_string();
        assert!(deep.contains("no surface found"), "{deep}");
        let mut clay = ball();
        let outside = add_pins(&mut clay, &PinRequest::Point(Vec3::splat(40.0)))
            .unwrap_err()
            .to_string();
        assert!(outside.contains("outside"), "{outside}");
        let short = add_pins(&mut clay, &PinRequest::Curve(vec![Vec3::ONE]))
            .unwrap_err()
            .to_string();
        assert!(short.contains("at least 2"), "{short}");
        assert!(clay.constraints.is_empty(), "nothing pinned");
    }

    #[test]
    fn a_pin_step_is_undone_and_redone_with_the_history() {
        use crate::tools::{History, StepRecorder};
        let mut clay = ball();
        let mut history = History::default();
        let pin = |clay: &mut Clay, history: &mut History, at: Vec3| {
            let mut rec = StepRecorder::new("pin");
            rec.touch_constraints(clay);
            add_pins(clay, &PinRequest::Point(at)).unwrap();
            assert!(history.commit(rec, clay), "a pin is an undo step");
        };
        pin(&mut clay, &mut history, Vec3::new(1.35, 0.95, 0.95));
        pin(&mut clay, &mut history, Vec3::new(0.95, 1.35, 0.95));
        let both = clay.constraints.clone();
        let mut rec = StepRecorder::new("unpin");
        rec.touch_constraints(&clay);
        remove_pins(&mut clay, None).unwrap();
        assert!(history.commit(rec, &clay));
        assert!(clay.constraints.is_empty());
        history.undo(&mut clay).unwrap();
        assert_eq!(clay.constraints, both, "undo of the removal");
        history.undo(&mut clay).unwrap();
        assert_eq!(clay.constraints, both[..1], "undo of the second pin");
        history.redo(&mut clay).unwrap();
        assert_eq!(clay.constraints, both, "redo of the second pin");
        // A recorder that saw no change of the list records nothing.
        let mut rec = StepRecorder::new("nothing");
        rec.touch_constraints(&clay);
        assert!(!history.commit(rec, &clay));
    }
}
