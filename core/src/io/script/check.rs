//! Validating each step: ranges, counts and finiteness, each refusal naming its key.

use super::*;

/// A step's parameter at fault: the key it is written under (whose line the error names)
/// and what is wrong with it.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{message}")]
pub struct StepFault {
    /// The step's key, as written in the script.
    pub key: &'static str,
    /// What is wrong, naming the value.
    pub message: String,
}

pub(super) fn fault(key: &'static str, message: impl Into<String>) -> StepFault {
    StepFault {
        key,
        message: message.into(),
    }
}

pub(super) fn finite(name: &'static str, v: f32) -> Result<(), StepFault> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(fault(
            name,
            format!("{name} = {v} must be finite and non-negative"),
        ))
    }
}

/// A duration or time of day on the script clock: finite, non-negative, at most
/// [`MAX_SCRIPT_SECONDS`].
pub(super) fn seconds(name: &'static str, v: f32) -> Result<(), StepFault> {
    seconds_shown(name, name, v)
}

/// [`seconds`] for the value `shown` (such as `times_s[2]`) written under `key`.
pub(super) fn seconds_shown(key: &'static str, shown: &str, v: f32) -> Result<(), StepFault> {
    if !(v.is_finite() && v >= 0.0) {
        return Err(fault(
            key,
            format!("{shown} = {v} must be finite and non-negative"),
        ));
    }
    if v > MAX_SCRIPT_SECONDS {
        return Err(fault(
            key,
            format!("{shown} = {v} s is longer than the {MAX_SCRIPT_SECONDS} s a script may last"),
        ));
    }
    Ok(())
}

/// Most particles a `particles` or `rbf` step may ask for.
pub const MAX_PARTICLES: u32 = 100_000;
/// Most particle steps a `particles` or `rbf` step may ask for.
pub const MAX_PARTICLE_STEPS: u32 = 100_000;
/// Most simulation steps per pull of a `points` step.
pub const MAX_POINTS_PULL_STEPS: u32 = 1_000_000;
/// Simulation steps per pull of a `points` step that names none.
pub const DEFAULT_POINTS_PULL_STEPS: u32 = 2000;
/// Most centres one dense RBF solve may take (`max_centres`).
pub const MAX_RBF_CENTRES: u32 = 6000;

/// The fewest particles a compact RBF clay (`compact_rbf`) holds.
pub const MIN_COMPACT_PARTICLES: usize = 8;
/// The most particles a compact RBF clay holds: its `3N` centres fit one dense solve of the
/// RBF's default size (3000 centres; `dynaclay_import::rbf::CompactSettings` checks it).
pub const MAX_COMPACT_PARTICLES: usize = 1000;

pub(super) fn check_particle_count(key: &'static str, n: u32) -> Result<(), StepFault> {
    if (4..=MAX_PARTICLES).contains(&n) {
        Ok(())
    } else {
        Err(fault(
            key,
            format!("{key} = {n} must be between 4 and {MAX_PARTICLES}"),
        ))
    }
}

pub(super) fn check_particle_steps(steps: Option<u32>) -> Result<(), StepFault> {
    match steps {
        Some(k) if !(1..=MAX_PARTICLE_STEPS).contains(&k) => Err(fault(
            "steps",
            format!("steps = {k} must be between 1 and {MAX_PARTICLE_STEPS}"),
        )),
        _ => Ok(()),
    }
}

pub(super) fn check_points(
    name: &'static str,
    points: &[[f32; 3]],
    need_one: bool,
) -> Result<(), StepFault> {
    if need_one && points.is_empty() {
        return Err(fault(name, format!("{name} needs at least one point")));
    }
    if points.len() > MAX_POINTS {
        return Err(fault(
            name,
            format!(
                "{name} has {} points; at most {MAX_POINTS} are allowed",
                points.len()
            ),
        ));
    }
    match points.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        Some(i) => Err(fault(name, format!("{name}[{i}] is not finite"))),
        None => Ok(()),
    }
}

/// A quaternion `[x, y, z, w]` that turns something: finite and not near zero (it is
/// normalised when used).
pub(super) fn check_rotation(key: &'static str, shown: &str, q: [f32; 4]) -> Result<(), StepFault> {
    let norm_sq: f32 = q.iter().map(|c| c * c).sum();
    if q.iter().all(|c| c.is_finite()) && norm_sq > 0.25 && norm_sq.is_finite() {
        Ok(())
    } else {
        Err(fault(
            key,
            format!(
                "{shown} = {q:?} is not a rotation (a finite quaternion [x, y, z, w] of length 1)"
            ),
        ))
    }
}

pub(super) fn check_step(step: &ScriptStep) -> Result<(), StepFault> {
    match step {
        ScriptStep::Tool {
            shape,
            action,
            positions,
            falloff_fu,
            rotation,
            duration_s,
            ..
        } => {
            check_points("positions", positions, true)?;
            if let Some(q) = rotation {
                check_rotation("rotation", "rotation", *q)?;
            }
            seconds("duration_s", *duration_s)?;
            finite("falloff_fu", *falloff_fu)?;
            action
                .validate()
                .map_err(|e| fault("action", format!("action: {}", e.0)))?;
            // Freeform shapes are checked against the library when run.
            if let Ok(shape) = shape.resolve(|_| None) {
                shape
                    .validate()
                    .map_err(|e| fault("shape", format!("shape: {}", e.0)))?;
            }
            Ok(())
        }
        ScriptStep::Preset {
            positions,
            duration_s,
            ..
        } => {
            check_points("positions", positions, true)?;
            seconds("duration_s", *duration_s)
        }
        ScriptStep::Stroke {
            tool,
            shape,
            action,
            falloff_fu,
            path,
            rotations,
            duration_s,
            times_s,
            start_s,
            hover_fu,
            curve,
            pivot,
            ..
        } => {
            check_points("path", path, true)?;
            if !rotations.is_empty() {
                if rotations.len() != path.len() {
                    return Err(fault(
                        "rotations",
                        format!(
                            "rotations has {} entries but path has {} points",
                            rotations.len(),
                            path.len()
                        ),
                    ));
                }
                for (i, q) in rotations.iter().enumerate() {
                    check_rotation("rotations", &format!("rotations[{i}]"), *q)?;
                }
            }
            check_points("curve", curve, false)?;
            if let Some(d) = duration_s {
                seconds("duration_s", *d)?;
                if !times_s.is_empty() {
                    return Err(fault(
                        "duration_s",
                        "duration_s: give either duration_s or times_s, not both",
                    ));
                }
            }
            if !times_s.is_empty() {
                if times_s.len() != path.len() {
                    return Err(fault(
                        "times_s",
                        format!(
                            "times_s has {} entries but path has {} points",
                            times_s.len(),
                            path.len()
                        ),
                    ));
                }
                for (i, t) in times_s.iter().enumerate() {
                    seconds_shown("times_s", &format!("times_s[{i}]"), *t)?;
                    if i > 0 && *t <= times_s[i - 1] {
                        return Err(fault(
                            "times_s",
                            format!("times_s[{i}] = {t} must be after times_s[{}]", i - 1),
                        ));
                    }
                }
            }
            if let Some(t) = start_s
                && !(t.is_finite() && *t >= 0.0 && *t <= f64::from(MAX_SCRIPT_SECONDS))
            {
                return Err(fault(
                    "start_s",
                    format!("start_s = {t} must be between 0 and {MAX_SCRIPT_SECONDS} s"),
                ));
            }
            if !(hover_fu.is_finite() && *hover_fu > 0.0) {
                return Err(fault(
                    "hover_fu",
                    format!("hover_fu = {hover_fu} must be positive"),
                ));
            }
            if let Some(p) = pivot {
                check_points("pivot", std::slice::from_ref(p), true)?;
            }
            match (tool, shape, action) {
                (Some(_), Some(_), _) | (Some(_), _, Some(_)) => Err(fault(
                    "tool",
                    "tool: give either tool (a force tool) or shape and action (a geometric \
                     tool), not both",
                )),
                (Some(tool), None, None) => tool
                    .validate()
                    .map_err(|e| fault("tool", format!("tool: {e}"))),
                (None, Some(_), None) => Err(fault("shape", "shape needs an action")),
                (None, None, Some(_)) => Err(fault("action", "action needs a shape")),
                (None, Some(shape), Some(action)) => {
                    action
                        .validate()
                        .map_err(|e| fault("action", format!("action: {}", e.0)))?;
                    finite("falloff_fu", *falloff_fu)?;
                    if let Ok(shape) = shape.resolve(|_| None) {
                        shape
                            .validate()
                            .map_err(|e| fault("shape", format!("shape: {}", e.0)))?;
                    }
                    Ok(())
                }
                (None, None, None) => Ok(()),
            }
        }
        ScriptStep::Material {
            mass,
            damping,
            stiffness,
            plasticity_per_s,
            yield_density,
            neighbourhood,
        } => {
            if let Some(n) = neighbourhood
                && Neighbourhood::from_count(*n).is_none()
            {
                return Err(fault(
                    "neighbourhood",
                    format!("neighbourhood = {n}: the springs join 6, 18 or 26 neighbours"),
                ));
            }
            for (name, v) in [
                ("mass", mass),
                ("damping", damping),
                ("stiffness", stiffness),
                ("plasticity_per_s", plasticity_per_s),
                ("yield_density", yield_density),
            ] {
                if let Some(v) = v {
                    finite(name, *v)?;
                }
            }
            if mass.is_some_and(|m| m <= 0.0) {
                return Err(fault("mass", "mass must be positive"));
            }
            Ok(())
        }
        ScriptStep::PaintMaterial { .. } => paint_request(step).map(|_| ()),
        ScriptStep::Mask { .. } | ScriptStep::MaskInvert | ScriptStep::MaskClear => {
            mask_request(step).map(|_| ())
        }
        ScriptStep::Undo { count } | ScriptStep::Redo { count } if *count > MAX_UNDO_COUNT => {
            Err(fault(
                "count",
                format!(
                    "count = {count} is more than the {MAX_UNDO_COUNT} steps one undo or redo may take"
                ),
            ))
        }
        ScriptStep::Constrain { kind, at, points } => pin_request(*kind, *at, points).map(|_| ()),
        ScriptStep::Unconstrain { index: Some(i) } if *i < 0 || *i >= MAX_CONSTRAINTS as i64 => {
            Err(fault(
                "index",
                format!("index = {i} must be between 0 and {}", MAX_CONSTRAINTS - 1),
            ))
        }
        ScriptStep::Emboss { depth, .. } => {
            if !(depth.is_finite() && *depth > 0.0) {
                return Err(fault("depth", format!("depth = {depth} must be positive")));
            }
            step.emboss_params().map_or(Ok(()), |params| {
                params
                    .validate()
                    .map_err(|m| fault("projection", format!("projection: {m}")))
            })
        }
        ScriptStep::Detail {
            automatic,
            force_tools,
        } => {
            if automatic.is_none() && force_tools.is_none() {
                return Err(fault(
                    "automatic",
                    "a detail step sets `automatic`, `force_tools` or both (true or false)",
                ));
            }
            Ok(())
        }
        ScriptStep::Refine { min, max, level } => {
            for (name, corner) in [("min", min), ("max", max)] {
                for v in corner {
                    finite(name, *v)?;
                }
            }
            if (0..3).any(|a| min[a] >= max[a]) {
                return Err(fault(
                    "max",
                    format!("the box {min:?}..{max:?} is empty: max must exceed min on every axis"),
                ));
            }
            if !(1..=crate::field::MAX_DETAIL_LEVEL).contains(level) {
                return Err(fault(
                    "level",
                    format!(
                        "level = {level} must be between 1 and {} (each level halves the knot spacing)",
                        crate::field::MAX_DETAIL_LEVEL
                    ),
                ));
            }
            Ok(())
        }
        ScriptStep::Particles {
            count, steps, out, ..
        } => {
            check_particle_count("count", *count)?;
            check_particle_steps(*steps)?;
            match out {
                Some(path) if path.as_os_str().is_empty() => {
                    Err(fault("out", "out must name a file"))
                }
                _ => Ok(()),
            }
        }
        ScriptStep::Points {
            input,
            pull,
            steps,
            out,
        } => {
            if input.as_os_str().is_empty() {
                return Err(fault("input", "input must name a point cloud file"));
            }
            if out
                .extension()
                .and_then(|e| e.to_str())
                .map(str::to_ascii_lowercase)
                .as_deref()
                != Some("ply")
            {
                return Err(fault(
                    "out",
                    format!("out = {:?} must end in .ply", out.display().to_string()),
                ));
            }
            check_points("pull", pull, false)?;
            match steps {
                Some(k) if !(1..=MAX_POINTS_PULL_STEPS).contains(k) => Err(fault(
                    "steps",
                    format!("steps = {k} must be between 1 and {MAX_POINTS_PULL_STEPS}"),
                )),
                _ => Ok(()),
            }
        }
        ScriptStep::Rbf {
            out,
            particles,
            offset,
            max_centres,
            steps,
            ..
        } => {
            if out.extension().and_then(|e| e.to_str()) != Some("rbf") {
                return Err(fault(
                    "out",
                    format!("out = {:?} must end in .rbf", out.display().to_string()),
                ));
            }
            if let Some(n) = particles {
                check_particle_count("particles", *n)?;
            }
            check_particle_steps(*steps)?;
            if let Some(d) = offset
                && !(d.is_finite() && *d > 0.0)
            {
                return Err(fault("offset", format!("offset = {d} must be positive")));
            }
            if let Some(m) = max_centres
                && !(4..=MAX_RBF_CENTRES).contains(m)
            {
                return Err(fault(
                    "max_centres",
                    format!("max_centres = {m} must be between 4 and {MAX_RBF_CENTRES}"),
                ));
            }
            Ok(())
        }
        ScriptStep::CompactRbf { particles } => {
            let (lo, hi) = (MIN_COMPACT_PARTICLES, MAX_COMPACT_PARTICLES);
            if *particles == 0 || (lo..=hi).contains(&(*particles as usize)) {
                Ok(())
            } else {
                Err(fault(
                    "particles",
                    format!("particles = {particles} must be 0 (off) or between {lo} and {hi}"),
                ))
            }
        }
        ScriptStep::MakeTool {
            name,
            selection,
            action,
            falloff_fu,
        } => {
            if name.is_empty() || name.len() > crate::io::MAX_TOOL_NAME_BYTES {
                return Err(fault(
                    "name",
                    format!(
                        "name must be 1 to {} bytes, got {}",
                        crate::io::MAX_TOOL_NAME_BYTES,
                        name.len()
                    ),
                ));
            }
            match selection {
                SelectionSpec::Box { min, max } => {
                    check_points("selection", &[*min, *max], true)?;
                    if (0..3).any(|a| min[a] >= max[a]) {
                        return Err(fault(
                            "selection",
                            format!(
                                "selection: the box {min:?}..{max:?} is empty: max must exceed \
                                 min on every axis"
                            ),
                        ));
                    }
                }
                SelectionSpec::Ball { centre, radius_fu } => {
                    check_points("selection", &[*centre], true)?;
                    if !(radius_fu.is_finite() && *radius_fu > 0.0) {
                        return Err(fault(
                            "selection",
                            format!("selection: radius_fu = {radius_fu} must be positive"),
                        ));
                    }
                }
            }
            finite("falloff_fu", *falloff_fu)?;
            action
                .validate()
                .map_err(|e| fault("action", format!("action: {}", e.0)))
        }
        ScriptStep::Csg {
            with,
            shape,
            position,
            falloff_fu,
            ..
        } => match (with, shape, position) {
            (Some(_), None, None) => Ok(()),
            (None, Some(_), Some(p)) => {
                check_points("position", &[*p], true)?;
                if falloff_fu.is_finite() && *falloff_fu > 0.0 {
                    Ok(())
                } else {
                    Err(fault(
                        "falloff_fu",
                        format!("falloff_fu = {falloff_fu} must be positive for a solid"),
                    ))
                }
            }
            (None, Some(_), None) => Err(fault(
                "position",
                "a csg step with a solid `shape` needs its `position`",
            )),
            _ => Err(fault(
                "with",
                "a csg step takes either `with` (a session file) or `shape` and `position` \
                 (a solid), not both and not neither",
            )),
        },
        ScriptStep::Unconstrain { .. }
        | ScriptStep::Undo { .. }
        | ScriptStep::Redo { .. }
        | ScriptStep::Save { .. } => Ok(()),
    }
}
