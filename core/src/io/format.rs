//! The session file's byte format: a versioned header, then checksummed sections. Encoding
//! and decoding are pure functions over byte slices; decoding validates everything before it
//! returns a session, so a bad file yields an error and no partial state.
//!
//! Layout (all integers and floats little-endian):
//!
//! ```text
//! header   magic "DYNACLAY" (8) | format version u32 | section count u32 | flags u32 | CRC32 of the previous 20 bytes u32
//! section  tag [u8; 4] | payload length u64 | payload | CRC32 of tag, length and payload u32
//! ```
//!
//! Sections in order: `META` (JSON metadata), one `PTCH` per patch (a lattice), `MATL`
//! (material: mass, damping, stiffness, plasticity, yield, then named grids), `COLR` (four lattices, only when the clay has colour), `TOOL` (the tool
//! library), `PINS` (the clay's geometric constraints as a JSON list, only when it has some;
//! files without it read as having none), `SPRG` (the material's spring neighbourhood as a
//! `u32`: 18 or 26, only when it is not the six-neighbour default; files without it read as
//! six), `END ` (empty). A lattice is dims `3 × u32`, spacing `f32`, origin `3 × f32`,
//! iso `f32`, coefficient count `u64`, coefficients `f32`. Sections with unknown tags are
//! checked and skipped, so later minor additions stay readable.
//!
//! Version 2 adds each patch's map `T_i` (world → patch space, eq. (3)) after its lattice in
//! `PTCH`: the linear part column by column, then the translation, 12 × `f32`. Version 1 files
//! have no map and read with the identity.
//!
//! Version 3 adds `MASK` (after `SPRG`, only when the clay has a freeze mask): the patch count
//! `u32`, then one lattice per patch, in patch order, each with its patch's dims and every hold
//! within `[0, 1]`. Files of versions 1 and 2 read with no mask.
//!
//! Version 4 stores the clay's lattices (each patch's in `PTCH`, the four in `COLR`, the
//! mask's in `MASK`) sparsely, in the 8×8×8 bricks the clay keeps them in
//! ([`crate::field::BrickedCoeffs`]): the lattice header as before, but the coefficient count
//! replaced by the brick count `u64` (`⌈nx/8⌉ · ⌈ny/8⌉ · ⌈nz/8⌉`), then brick records in
//! directory order (x fastest):
//!
//! ```text
//! run    0u8 | bricks u32 (at least 1, at most the bricks left) | value f32   every coefficient the bricks own is `value`
//! dense  1u8 | the coefficients the brick owns inside the lattice, f32, x fastest (8³, fewer at a high border)
//! ```
//!
//! A brick's apron (the copies of its neighbours' coefficients it keeps in memory) is never
//! written: loading rebuilds it, and a brick whose own coefficients and apron all agree is
//! uniform again, so a loaded clay holds no more dense bricks than the one saved. Loading
//! applies the budgets editing keeps (see [`crate::field::MAX_DENSE_BRICKS`]), so a clay that
//! saves loads and one past them is refused. Before anything is allocated for a lattice its
//! dims are checked against the clay's box budget ([`MAX_CLAY_BOX_COEFFS`] for every lattice
//! read so far together, the check a refine and a growth make, which bounds the brick
//! directory; a mask lattice must have its patch's dims) and its brick count against its
//! dims; a run's length against the bricks left, a dense brick's values against the bytes
//! left; and each dense brick, the ones the file gives and the ones an apron needs, against
//! the dense bricks the clay's budget leaves ([`MAX_DENSE_BRICKS`] for every lattice
//! together), before it is allocated: the ones the aprons need are counted before any of them
//! is made, so a file of uniform runs that would need too many costs only its directory. The tool library's freeform lattices stay dense
//! (they are small, and their size is bounded by the bytes that hold them).

use std::path::Path;

use dynaclay_files::ByteCursor;
use glam::{Affine3A, Vec3};

use super::error::SessionError;
use super::session::{MaterialFields, MaterialGrid, Session, SessionMeta, ToolPreset};
use crate::dynamics::{Constraint, MAX_CONSTRAINTS, Material, Neighbourhood};
use crate::field::{
    BSplineLattice, BrickedCoeffs, COEFF_BRICK, COEFF_BRICK_VALUES, DENSE_BRICK_BUDGET_BYTES,
    MAX_CLAY_BOX_COEFFS, MAX_DENSE_BRICKS, MAX_PATCHES, OwnedBrick, OwnedBricksError, Patch,
};
use crate::tools::{Clay, ColourField, FreeformTool, FreezeMask, ToolAction, ToolShape};

/// The first eight bytes of every session file.
pub const MAGIC: [u8; 8] = *b"DYNACLAY";
/// The format version this build writes and the newest it reads.
pub const FORMAT_VERSION: u32 = 4;
const HEADER_LEN: usize = 24;

const META: [u8; 4] = *b"META";
const PATCH: [u8; 4] = *b"PTCH";
/// The most a patch's map may scale space, either way (by a column of it or of its inverse).
pub const MAX_MAP_SCALE: f32 = 1e3;
const MATERIAL: [u8; 4] = *b"MATL";
const COLOUR: [u8; 4] = *b"COLR";
const TOOLS: [u8; 4] = *b"TOOL";
const PINS: [u8; 4] = *b"PINS";
const SPRINGS: [u8; 4] = *b"SPRG";
const MASK: [u8; 4] = *b"MASK";
const END: [u8; 4] = *b"END ";
/// The first format version whose clay lattices are stored as brick records.
const BRICKED_VERSION: u32 = 4;
/// A brick record: a run of uniform bricks.
const UNIFORM_RUN: u8 = 0;
/// A brick record: one dense brick's own coefficients.
const DENSE_BRICK: u8 = 1;

/// Serialises a session.
///
/// # Errors
/// [`SessionError::Invalid`] when a lattice's coefficient count mismatches its dimensions or
/// the metadata cannot be encoded.
pub fn encode(session: &Session) -> Result<Vec<u8>, SessionError> {
    encode_version(session, FORMAT_VERSION)
}

/// [`encode`] in format `version`, for a build that reads only older files (and for tests
/// that check such files still read): 1 writes no patch maps, 2 no freeze mask, 3 every
/// coefficient of every lattice; [`FORMAT_VERSION`] is what [`encode`] writes.
///
/// # Errors
/// [`SessionError::Invalid`] for a version outside `1..=FORMAT_VERSION`, and as [`encode`].
pub fn encode_version(session: &Session, version: u32) -> Result<Vec<u8>, SessionError> {
    if !(1..=FORMAT_VERSION).contains(&version) {
        return Err(SessionError::Invalid {
            detail: format!(
                "format version {version}; this build writes versions 1 to {FORMAT_VERSION}"
            ),
        });
    }
    let meta = serde_json::to_vec(&session.meta).map_err(|e| SessionError::Invalid {
        detail: format!("metadata: {e}"),
    })?;
    let coeff_bytes: usize = session
        .clay
        .density
        .patches
        .iter()
        .map(|p| {
            let values = if version >= BRICKED_VERSION {
                COEFF_BRICK_VALUES * p.lattice.coeffs.dense_brick_count()
            } else {
                p.lattice.coeffs.len()
            };
            4 * values + 104
        })
        .sum();
    let mut out = Vec::with_capacity(HEADER_LEN + meta.len() + coeff_bytes + 4096);
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&version.to_le_bytes());
    out.extend_from_slice(&0_u32.to_le_bytes()); // section count, patched below
    out.extend_from_slice(&0_u32.to_le_bytes());
    out.extend_from_slice(&0_u32.to_le_bytes()); // header CRC, patched below
    // Sections are written in place (one copy of the coefficients; see bench/tools.rs).
    let mut count = 0_u32;
    let mut section = |out: &mut Vec<u8>,
                       tag: [u8; 4],
                       write: &mut dyn FnMut(&mut Vec<u8>) -> Result<(), SessionError>|
     -> Result<(), SessionError> {
        let start = out.len();
        out.extend_from_slice(&tag);
        out.extend_from_slice(&0_u64.to_le_bytes());
        write(out)?;
        let len = (out.len() - start - 12) as u64;
        out[start + 4..start + 12].copy_from_slice(&len.to_le_bytes());
        let crc = crc32fast::hash(&out[start..]);
        out.extend_from_slice(&crc.to_le_bytes());
        count += 1;
        Ok(())
    };
    section(&mut out, META, &mut |o| {
        o.extend_from_slice(&meta);
        Ok(())
    })?;
    for (n, patch) in session.clay.density.patches.iter().enumerate() {
        section(&mut out, PATCH, &mut |o| {
            put_clay_lattice(o, version, &patch.lattice, &format!("patch {n}"))?;
            if version >= 2 {
                put_map(o, &patch.world_to_patch, &format!("patch {n}"))?;
            }
            Ok(())
        })?;
    }
    section(&mut out, MATERIAL, &mut |o| {
        o.extend_from_slice(&encode_material(&session.material)?);
        Ok(())
    })?;
    if let Some(colour) = &session.clay.colour {
        section(&mut out, COLOUR, &mut |o| {
            for (c, channel) in colour.channels.iter().enumerate() {
                put_clay_lattice(o, version, channel, &format!("colour channel {c}"))?;
            }
            Ok(())
        })?;
    }
    section(&mut out, TOOLS, &mut |o| {
        o.extend_from_slice(&encode_tools(&session.tools)?);
        Ok(())
    })?;
    if !session.clay.constraints.is_empty() {
        let pins =
            serde_json::to_vec(&session.clay.constraints).map_err(|e| SessionError::Invalid {
                detail: format!("constraints: {e}"),
            })?;
        section(&mut out, PINS, &mut |o| {
            o.extend_from_slice(&pins);
            Ok(())
        })?;
    }
    let neighbourhood = session.material.uniform.neighbourhood;
    if neighbourhood != Neighbourhood::Six {
        section(&mut out, SPRINGS, &mut |o| {
            o.extend_from_slice(&neighbourhood.count().to_le_bytes());
            Ok(())
        })?;
    }
    if let Some(mask) = session.clay.mask.as_ref().filter(|_| version >= 3) {
        section(&mut out, MASK, &mut |o| {
            let count = u32::try_from(mask.patches.len()).map_err(|_| SessionError::Invalid {
                detail: format!("the mask covers {} patches", mask.patches.len()),
            })?;
            o.extend_from_slice(&count.to_le_bytes());
            for (n, holds) in mask.patches.iter().enumerate() {
                put_clay_lattice(o, version, holds, &format!("mask over patch {n}"))?;
            }
            Ok(())
        })?;
    }
    section(&mut out, END, &mut |_| Ok(()))?;
    out[12..16].copy_from_slice(&count.to_le_bytes());
    let crc = crc32fast::hash(&out[..20]);
    out[20..24].copy_from_slice(&crc.to_le_bytes());
    Ok(out)
}

/// Parses and validates a session; `path` only names the file in errors.
///
/// # Errors
/// [`SessionError::NotASession`] for a foreign file, [`SessionError::UnsupportedVersion`],
/// [`SessionError::Truncated`], [`SessionError::Checksum`] and [`SessionError::Malformed`]
/// naming the section and byte offset; a clay past the budgets of editing (its box, its
/// dense bricks: see [`crate::field::MAX_DENSE_BRICKS`]) is `Malformed`, refused before the
/// lattice past them is allocated.
pub fn decode(bytes: &[u8], path: &Path) -> Result<Session, SessionError> {
    decode_within(bytes, path, MAX_DENSE_BRICKS)
}

/// [`decode`] for a clay that may hold at most `dense_budget` dense bricks.
fn decode_within(bytes: &[u8], path: &Path, dense_budget: usize) -> Result<Session, SessionError> {
    let truncated = |section: &str, offset: usize, needed: usize| SessionError::Truncated {
        path: path.to_path_buf(),
        section: section.to_string(),
        offset: offset as u64,
        needed: needed as u64,
        available: bytes.len().saturating_sub(offset) as u64,
    };
    if bytes.is_empty() {
        return Err(SessionError::Empty {
            path: path.to_path_buf(),
        });
    }
    if bytes.len() < 8 || bytes[..8] != MAGIC {
        let mut found = [0_u8; 8];
        let n = bytes.len().min(8);
        found[..n].copy_from_slice(&bytes[..n]);
        return Err(SessionError::NotASession {
            path: path.to_path_buf(),
            found,
        });
    }
    if bytes.len() < HEADER_LEN {
        return Err(truncated("header", 0, HEADER_LEN));
    }
    let u32_at = |o: usize| u32::from_le_bytes(bytes[o..o + 4].try_into().expect("4 bytes"));
    let stored = u32_at(20);
    let computed = crc32fast::hash(&bytes[..20]);
    if stored != computed {
        return Err(SessionError::Checksum {
            path: path.to_path_buf(),
            section: "header".into(),
            offset: 0,
            stored,
            computed,
        });
    }
    let version = u32_at(8);
    if version == 0 || version > FORMAT_VERSION {
        return Err(SessionError::UnsupportedVersion {
            path: path.to_path_buf(),
            found: version,
            supported: FORMAT_VERSION,
        });
    }
    let count = u32_at(12) as usize;
    if count == 0 {
        return Err(SessionError::Malformed {
            path: path.to_path_buf(),
            section: "header".into(),
            offset: 12,
            detail: "the section count is 0; a session holds at least its END section".into(),
        });
    }

    let mut session = Session::default();
    let mut meta_seen = false;
    let mut material_seen = false;
    let mut neighbourhood = Neighbourhood::Six;
    let mut ended = false;
    let mut pos = HEADER_LEN;
    for index in 0..count {
        let label = format!("#{index}");
        if bytes.len() - pos < 12 {
            return Err(truncated(&label, pos, 12));
        }
        let tag: [u8; 4] = bytes[pos..pos + 4].try_into().expect("4 bytes");
        let name = format!("{} ({label})", String::from_utf8_lossy(&tag));
        let len = u64::from_le_bytes(bytes[pos + 4..pos + 12].try_into().expect("8 bytes"));
        let available = (bytes.len() - pos - 12) as u64;
        if len.saturating_add(4) > available {
            return Err(SessionError::Truncated {
                path: path.to_path_buf(),
                section: name,
                offset: pos as u64,
                needed: len.saturating_add(16),
                available: available + 12,
            });
        }
        let len = len as usize;
        let end = pos + 12 + len;
        let stored = u32::from_le_bytes(bytes[end..end + 4].try_into().expect("4 bytes"));
        let computed = crc32fast::hash(&bytes[pos..end]);
        if stored != computed {
            return Err(SessionError::Checksum {
                path: path.to_path_buf(),
                section: name,
                offset: pos as u64,
                stored,
                computed,
            });
        }
        if ended {
            return Err(malformed(path, &name, pos, "section after END"));
        }
        let mut r = Reader {
            cursor: ByteCursor::new(&bytes[pos + 12..end]),
            base: pos + 12,
            section: &name,
            path,
        };
        match tag {
            META => {
                session.meta = serde_json::from_slice::<SessionMeta>(r.cursor.bytes())
                    .map_err(|e| r.error(&format!("metadata JSON: {e}")))?;
                meta_seen = true;
            }
            PATCH => {
                if session.clay.density.patches.len() >= MAX_PATCHES {
                    return Err(r.error(&format!(
                        "more than {MAX_PATCHES} patches; a clay holds at most {MAX_PATCHES}"
                    )));
                }
                let before = session.clay.box_coefficient_count() as u64;
                let dense_room = dense_room(&session.clay, dense_budget);
                let lattice = r.clay_lattice(version, dense_room, |_, count| {
                    let total = before.saturating_add(count);
                    if total > MAX_CLAY_BOX_COEFFS as u64 {
                        Err(format!(
                            "the clay spans {total} coefficients of box with this patch; at most {MAX_CLAY_BOX_COEFFS}"
                        ))
                    } else {
                        Ok(())
                    }
                })?;
                let world_to_patch = if version >= 2 {
                    r.map()?
                } else {
                    Affine3A::IDENTITY
                };
                session.clay.density.patches.push(Patch {
                    lattice,
                    world_to_patch,
                });
            }
            MATERIAL => {
                session.material = decode_material(&mut r)?;
                material_seen = true;
            }
            COLOUR => {
                // The channels read so far count against the clay's budgets too.
                let mut box_total = session.clay.box_coefficient_count() as u64;
                let mut dense_left = dense_room(&session.clay, dense_budget);
                let mut channel = || {
                    let lattice = r.clay_lattice(version, dense_left, |_, count| {
                        let total = box_total.saturating_add(count);
                        if total > MAX_CLAY_BOX_COEFFS as u64 {
                            Err(format!(
                                "the clay spans {total} coefficients of box with this colour channel; at most {MAX_CLAY_BOX_COEFFS}"
                            ))
                        } else {
                            Ok(())
                        }
                    })?;
                    box_total += lattice.coeffs.len() as u64;
                    dense_left -= lattice.coeffs.dense_brick_count();
                    Ok::<_, SessionError>(lattice)
                };
                let channels = [channel()?, channel()?, channel()?, channel()?];
                let colour = ColourField { channels };
                if !colour.is_consistent() {
                    return Err(r.error("colour channels differ in geometry"));
                }
                session.clay.colour = Some(colour);
            }
            TOOLS => session.tools = decode_tools(&mut r)?,
            PINS => session.clay.constraints = decode_pins(&r)?,
            SPRINGS => {
                let count = r.u32()?;
                let Some(nb) = Neighbourhood::from_count(count) else {
                    r.cursor.rewind_to(0);
                    return Err(r.error(&format!(
                        "spring neighbourhood {count}; it must be 6, 18 or 26"
                    )));
                };
                neighbourhood = nb;
            }
            MASK => {
                let room = dense_room(&session.clay, dense_budget);
                session.clay.mask = Some(decode_mask(&mut r, version, &session.clay, room)?);
            }
            END => ended = true,
            // Unknown but intact: a later minor addition; skip it.
            _ => {}
        }
        if matches!(
            tag,
            PATCH | MATERIAL | COLOUR | TOOLS | SPRINGS | MASK | END
        ) {
            r.finish()?;
        }
        pos = end + 4;
    }
    if !ended {
        return Err(truncated("END", pos, 16));
    }
    if pos != bytes.len() {
        return Err(malformed(
            path,
            "trailer",
            pos,
            &format!("{} unexpected bytes after END", bytes.len() - pos),
        ));
    }
    if !meta_seen || !material_seen {
        return Err(malformed(path, "header", 0, "missing META or MATL section"));
    }
    session.material.uniform.neighbourhood = neighbourhood;
    Ok(session)
}

/// The `MASK` section: one hold lattice per patch already read, each with its patch's dims and
/// every hold within `[0, 1]`.
fn decode_mask(
    r: &mut Reader,
    version: u32,
    clay: &Clay,
    dense_room: usize,
) -> Result<FreezeMask, SessionError> {
    let count = r.u32()? as usize;
    let patches = clay.density.patches.len();
    if count != patches {
        r.cursor.rewind_to(0);
        return Err(r.error(&format!(
            "the mask covers {count} patches; the clay read so far has {patches}"
        )));
    }
    let mut holds = Vec::with_capacity(count);
    let mut dense_left = dense_room;
    let mut box_total = clay.box_coefficient_count() as u64;
    for (n, patch) in clay.density.patches.iter().enumerate() {
        let lattice = r.clay_lattice(version, dense_left, |dims, count| {
            let total = box_total.saturating_add(count);
            if dims != patch.lattice.dims {
                Err(format!(
                    "the mask over patch {n} has dims {dims:?}; the patch has {:?}",
                    patch.lattice.dims
                ))
            } else if total > MAX_CLAY_BOX_COEFFS as u64 {
                Err(format!(
                    "the clay spans {total} coefficients of box with the mask over patch {n}; at most {MAX_CLAY_BOX_COEFFS}"
                ))
            } else {
                Ok(())
            }
        })?;
        dense_left -= lattice.coeffs.dense_brick_count();
        box_total += lattice.coeffs.len() as u64;
        if let Some(bad) = lattice.coeffs.iter().find(|h| !(0.0..=1.0).contains(*h)) {
            return Err(r.error(&format!(
                "a hold of the mask over patch {n} is {bad}; holds lie within [0, 1]"
            )));
        }
        holds.push(lattice);
    }
    Ok(FreezeMask { patches: holds })
}

/// Dense bricks the clay read so far leaves to the lattices still to come, of `budget`.
fn dense_room(clay: &Clay, budget: usize) -> usize {
    budget.saturating_sub(clay.dense_brick_count())
}

/// Why a lattice that would make the clay hold too many dense bricks is refused.
fn too_many_dense(max_dense: usize) -> String {
    format!(
        "the lattice holds more than the {max_dense} dense bricks the clay's budget leaves it \
         (a clay holds at most {MAX_DENSE_BRICKS} dense bricks, {} MiB)",
        DENSE_BRICK_BUDGET_BYTES >> 20
    )
}

/// The `PINS` section: a JSON list of constraints, each checked, at most [`MAX_CONSTRAINTS`].
fn decode_pins(r: &Reader) -> Result<Vec<Constraint>, SessionError> {
    let pins: Vec<Constraint> = serde_json::from_slice(r.cursor.bytes())
        .map_err(|e| r.error(&format!("constraints JSON: {e}")))?;
    if pins.len() > MAX_CONSTRAINTS {
        return Err(r.error(&format!(
            "{} constraints; at most {MAX_CONSTRAINTS} are allowed",
            pins.len()
        )));
    }
    for (i, pin) in pins.iter().enumerate() {
        pin.validate()
            .map_err(|e| r.error(&format!("constraint {i}: {e}")))?;
    }
    Ok(pins)
}

fn malformed(path: &Path, section: &str, offset: usize, detail: &str) -> SessionError {
    SessionError::Malformed {
        path: path.to_path_buf(),
        section: section.to_string(),
        offset: offset as u64,
        detail: detail.to_string(),
    }
}

fn put_lattice(out: &mut Vec<u8>, l: &BSplineLattice, what: &str) -> Result<(), SessionError> {
    if l.coeffs.len() != l.dims.iter().product::<usize>() {
        return Err(SessionError::Invalid {
            detail: format!(
                "{what}: {} coefficients for dims {:?}",
                l.coeffs.len(),
                l.dims
            ),
        });
    }
    put_lattice_frame(out, l, what)?;
    out.extend_from_slice(&(l.coeffs.len() as u64).to_le_bytes());
    put_f32s(out, &l.coeffs.to_vec());
    Ok(())
}

/// A lattice's dims, spacing, origin and iso-level.
fn put_lattice_frame(
    out: &mut Vec<u8>,
    l: &BSplineLattice,
    what: &str,
) -> Result<(), SessionError> {
    for d in l.dims {
        let d = u32::try_from(d).map_err(|_| SessionError::Invalid {
            detail: format!("{what}: dimension {d} too large"),
        })?;
        out.extend_from_slice(&d.to_le_bytes());
    }
    out.extend_from_slice(&l.spacing.to_le_bytes());
    for a in 0..3 {
        out.extend_from_slice(&l.origin[a].to_le_bytes());
    }
    out.extend_from_slice(&l.iso.to_le_bytes());
    Ok(())
}

/// A lattice of the clay (a patch, a colour channel, a mask): brick records from
/// [`BRICKED_VERSION`] on, every coefficient before.
fn put_clay_lattice(
    out: &mut Vec<u8>,
    version: u32,
    l: &BSplineLattice,
    what: &str,
) -> Result<(), SessionError> {
    if version < BRICKED_VERSION {
        return put_lattice(out, l, what);
    }
    if l.coeffs.dims() != l.dims {
        return Err(SessionError::Invalid {
            detail: format!(
                "{what}: coefficients of dims {:?} for a lattice of dims {:?}",
                l.coeffs.dims(),
                l.dims
            ),
        });
    }
    put_lattice_frame(out, l, what)?;
    out.extend_from_slice(&(l.coeffs.brick_count() as u64).to_le_bytes());
    // A run of uniform bricks of one value: its length and the value's bits.
    let mut run: Option<(u32, f32)> = None;
    let flush = |out: &mut Vec<u8>, run: Option<(u32, f32)>| {
        if let Some((bricks, value)) = run {
            out.push(UNIFORM_RUN);
            out.extend_from_slice(&bricks.to_le_bytes());
            out.extend_from_slice(&value.to_le_bytes());
        }
    };
    l.coeffs.for_each_owned_brick(|brick| match brick {
        OwnedBrick::Uniform(v) => match &mut run {
            Some((bricks, value)) if value.to_bits() == v.to_bits() && *bricks < u32::MAX => {
                *bricks += 1;
            }
            _ => {
                flush(out, run);
                run = Some((1, v));
            }
        },
        OwnedBrick::Values(values) => {
            flush(out, run.take());
            out.push(DENSE_BRICK);
            put_f32s(out, values);
        }
    });
    flush(out, run);
    Ok(())
}

/// A patch map `T_i`: the linear part column by column, then the translation.
fn put_map(out: &mut Vec<u8>, map: &Affine3A, what: &str) -> Result<(), SessionError> {
    if !map.is_finite() {
        return Err(SessionError::Invalid {
            detail: format!("{what}: the map to patch space is not finite"),
        });
    }
    put_f32s(out, &map.to_cols_array());
    Ok(())
}

fn put_f32s(out: &mut Vec<u8>, values: &[f32]) {
    if cfg!(target_endian = "little") {
        out.extend_from_slice(bytemuck::cast_slice(values));
    } else {
        for v in values {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
}

fn put_str(out: &mut Vec<u8>, s: &str) {
    out.extend_from_slice(&(s.len() as u32).to_le_bytes());
    out.extend_from_slice(s.as_bytes());
}

fn encode_material(m: &MaterialFields) -> Result<Vec<u8>, SessionError> {
    let mut out = Vec::new();
    let u = &m.uniform;
    for v in [
        u.mass,
        u.damping,
        u.stiffness,
        u.plasticity_per_s,
        u.yield_density,
    ] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out.extend_from_slice(&(m.grids.len() as u32).to_le_bytes());
    for g in &m.grids {
        if g.values.len() != g.dims.iter().product::<usize>() {
            return Err(SessionError::Invalid {
                detail: format!(
                    "material grid {}: {} values for dims {:?}",
                    g.name,
                    g.values.len(),
                    g.dims
                ),
            });
        }
        put_str(&mut out, &g.name);
        for d in g.dims {
            out.extend_from_slice(&(d as u32).to_le_bytes());
        }
        out.extend_from_slice(&(g.values.len() as u64).to_le_bytes());
        put_f32s(&mut out, &g.values);
    }
    Ok(out)
}

fn decode_material(r: &mut Reader) -> Result<MaterialFields, SessionError> {
    let start = r.cursor.at();
    let mut m = MaterialFields {
        uniform: Material {
            mass: r.f32()?,
            damping: r.f32()?,
            stiffness: r.f32()?,
            plasticity_per_s: r.f32()?,
            yield_density: r.f32()?,
            // From the `SPRG` section, when there is one.
            neighbourhood: Neighbourhood::Six,
        },
        grids: Vec::new(),
    };
    if let Err(e) = m.uniform.validate() {
        r.cursor.rewind_to(start);
        return Err(r.error(&e.to_string()));
    }
    let count = r.u32()?;
    for _ in 0..count {
        let name = r.string()?;
        let dims = [r.u32()? as usize, r.u32()? as usize, r.u32()? as usize];
        let at = r.cursor.at();
        let len = r.u64()?;
        if Some(len)
            != dims
                .iter()
                .try_fold(1_u64, |acc, &d| acc.checked_mul(d as u64))
        {
            r.cursor.rewind_to(at);
            return Err(r.error(&format!(
                "material grid {name}: {len} values for dims {dims:?}"
            )));
        }
        let values_at = r.cursor.at();
        let values = r.f32s(len)?;
        let grid = MaterialGrid { name, dims, values };
        if let Err(e) = grid.validate() {
            r.cursor.rewind_to(values_at);
            return Err(r.error(&e.to_string()));
        }
        m.grids.push(grid);
    }
    Ok(m)
}

// Shape tags in the TOOL section.
const SPHERE: u8 = 0;
const ELLIPSOID: u8 = 1;
const BOX: u8 = 2;
const CYLINDER: u8 = 3;
const CAPSULE: u8 = 4;
const FREEFORM: u8 = 5;
/// A round brush with a falloff curve: its radius, then the curve as a JSON string.
const PROFILED: u8 = 6;

fn encode_tools(tools: &[ToolPreset]) -> Result<Vec<u8>, SessionError> {
    let mut out = Vec::new();
    out.extend_from_slice(&(tools.len() as u32).to_le_bytes());
    for t in tools {
        put_str(&mut out, &t.name);
        let action = serde_json::to_string(&t.action).map_err(|e| SessionError::Invalid {
            detail: format!("tool {}: action: {e}", t.name),
        })?;
        put_str(&mut out, &action);
        out.extend_from_slice(&t.falloff_fu.to_le_bytes());
        let (tag, params): (u8, Vec<f32>) = match &t.shape {
            ToolShape::Sphere { radius_fu } => (SPHERE, vec![*radius_fu]),
            ToolShape::Ellipsoid { radii_fu } => (ELLIPSOID, radii_fu.to_array().to_vec()),
            ToolShape::Box { half_extents_fu } => (BOX, half_extents_fu.to_array().to_vec()),
            ToolShape::Cylinder {
                radius_fu,
                half_height_fu,
            } => (CYLINDER, vec![*radius_fu, *half_height_fu]),
            ToolShape::Capsule {
                radius_fu,
                half_height_fu,
            } => (CAPSULE, vec![*radius_fu, *half_height_fu]),
            ToolShape::Freeform(f) => (FREEFORM, f.scale.to_array().to_vec()),
            ToolShape::Profiled { radius_fu, .. } => (PROFILED, vec![*radius_fu]),
        };
        out.push(tag);
        put_f32s(&mut out, &params);
        if let ToolShape::Profiled { curve, .. } = &t.shape {
            let curve = serde_json::to_string(curve).map_err(|e| SessionError::Invalid {
                detail: format!("tool {}: falloff curve: {e}", t.name),
            })?;
            put_str(&mut out, &curve);
        }
        if let ToolShape::Freeform(f) = &t.shape {
            put_lattice(&mut out, &f.lattice, &format!("tool {}", t.name))?;
        }
    }
    Ok(out)
}

fn decode_tools(r: &mut Reader) -> Result<Vec<ToolPreset>, SessionError> {
    let count = r.u32()?;
    let mut tools = Vec::new();
    for _ in 0..count {
        let name = r.string()?;
        let at = r.cursor.at();
        let action_json = r.string()?;
        let action: ToolAction = serde_json::from_str(&action_json).map_err(|e| {
            r.cursor.rewind_to(at);
            r.error(&format!("tool {name}: action: {e}"))
        })?;
        let falloff_fu = r.f32()?;
        let at = r.cursor.at();
        let tag = r.u8()?;
        let shape = match tag {
            SPHERE => ToolShape::Sphere {
                radius_fu: r.f32()?,
            },
            ELLIPSOID => ToolShape::Ellipsoid {
                radii_fu: r.vec3()?,
            },
            BOX => ToolShape::Box {
                half_extents_fu: r.vec3()?,
            },
            CYLINDER => ToolShape::Cylinder {
                radius_fu: r.f32()?,
                half_height_fu: r.f32()?,
            },
            CAPSULE => ToolShape::Capsule {
                radius_fu: r.f32()?,
                half_height_fu: r.f32()?,
            },
            FREEFORM => {
                let scale = r.vec3()?;
                ToolShape::Freeform(FreeformTool {
                    lattice: r.lattice()?,
                    scale,
                })
            }
            PROFILED => {
                let radius_fu = r.f32()?;
                let curve_at = r.cursor.at();
                let curve_json = r.string()?;
                let curve = serde_json::from_str(&curve_json).map_err(|e| {
                    r.cursor.rewind_to(curve_at);
                    r.error(&format!("tool {name}: falloff curve: {e}"))
                })?;
                ToolShape::Profiled { radius_fu, curve }
            }
            other => {
                r.cursor.rewind_to(at);
                return Err(r.error(&format!("tool {name}: unknown shape tag {other}")));
            }
        };
        if let Err(e) = shape.validate() {
            r.cursor.rewind_to(at);
            return Err(r.error(&format!("tool {name}: {e}")));
        }
        tools.push(ToolPreset {
            name,
            shape,
            action,
            falloff_fu,
        });
    }
    Ok(tools)
}

/// A bounds-checked cursor over one section's payload; errors carry absolute byte offsets.
struct Reader<'a> {
    cursor: ByteCursor<'a>,
    base: usize,
    section: &'a str,
    path: &'a Path,
}

impl Reader<'_> {
    fn error(&self, detail: &str) -> SessionError {
        malformed(
            self.path,
            self.section,
            self.base + self.cursor.at(),
            detail,
        )
    }

    fn take(&mut self, n: usize) -> Result<&[u8], SessionError> {
        self.cursor.take(n).map_err(|short| {
            self.error(&format!(
                "needs {n} more bytes, the section has {} left",
                short.available
            ))
        })
    }

    fn u8(&mut self) -> Result<u8, SessionError> {
        Ok(self.take(1)?[0])
    }

    fn u32(&mut self) -> Result<u32, SessionError> {
        Ok(u32::from_le_bytes(
            self.take(4)?.try_into().expect("4 bytes"),
        ))
    }

    fn u64(&mut self) -> Result<u64, SessionError> {
        Ok(u64::from_le_bytes(
            self.take(8)?.try_into().expect("8 bytes"),
        ))
    }

    fn f32(&mut self) -> Result<f32, SessionError> {
        Ok(f32::from_le_bytes(
            self.take(4)?.try_into().expect("4 bytes"),
        ))
    }

    fn vec3(&mut self) -> Result<Vec3, SessionError> {
        Ok(Vec3::new(self.f32()?, self.f32()?, self.f32()?))
    }

    fn f32s(&mut self, count: u64) -> Result<Vec<f32>, SessionError> {
        let n = usize::try_from(count)
            .ok()
            .and_then(|c| c.checked_mul(4))
            .ok_or_else(|| self.error(&format!("{count} values do not fit in memory")))?;
        let raw = self.take(n)?;
        if cfg!(target_endian = "little") {
            // One copy into aligned memory (see bench/tools.rs, session_256/load_validated).
            Ok(bytemuck::pod_collect_to_vec(raw))
        } else {
            Ok(raw
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
                .collect())
        }
    }

    fn string(&mut self) -> Result<String, SessionError> {
        let len = self.u32()? as usize;
        let at = self.cursor.at();
        let raw = self.take(len)?.to_vec();
        String::from_utf8(raw).map_err(|e| {
            self.cursor.rewind_to(at);
            self.error(&format!("text is not UTF-8: {e}"))
        })
    }

    fn lattice(&mut self) -> Result<BSplineLattice, SessionError> {
        let start = self.cursor.at();
        let dims = [
            self.u32()? as usize,
            self.u32()? as usize,
            self.u32()? as usize,
        ];
        let spacing = self.f32()?;
        let origin = self.vec3()?;
        let iso = self.f32()?;
        let count = self.u64()?;
        let expected = dims
            .iter()
            .try_fold(1_u64, |acc, &d| acc.checked_mul(d as u64));
        if Some(count) != expected {
            self.cursor.rewind_to(start);
            return Err(self.error(&format!("lattice {dims:?} holds {count} coefficients")));
        }
        let values_at = self.cursor.at();
        let coeffs = self.f32s(count)?;
        if !(origin.is_finite() && iso.is_finite()) {
            self.cursor.rewind_to(start);
            return Err(self.error("lattice origin or iso-level is not finite"));
        }
        if !(spacing.is_finite() && spacing > 0.0) {
            self.cursor.rewind_to(start);
            return Err(self.error(&format!(
                "lattice spacing {spacing}: must be finite and above 0"
            )));
        }
        if let Some(i) = coeffs.iter().position(|c| !c.is_finite()) {
            // Point at the value itself.
            self.cursor.rewind_to(values_at + 4 * i);
            return Err(self.error(&format!(
                "lattice coefficient {i} is {}, not a finite number",
                coeffs[i]
            )));
        }
        let mut l = BSplineLattice::from_coeffs(dims, spacing, origin, coeffs).map_err(|e| {
            self.cursor.rewind_to(start);
            self.error(&format!("lattice: {e}"))
        })?;
        l.iso = iso;
        Ok(l)
    }

    /// A lattice of the clay: brick records from [`BRICKED_VERSION`] on (see
    /// [`Reader::bricked_lattice`]), every coefficient before. `admit` checks its dims and
    /// coefficient count (an error message when they are refused).
    fn clay_lattice(
        &mut self,
        version: u32,
        max_dense: usize,
        admit: impl FnOnce([usize; 3], u64) -> Result<(), String>,
    ) -> Result<BSplineLattice, SessionError> {
        if version >= BRICKED_VERSION {
            return self.bricked_lattice(max_dense, admit);
        }
        // Every coefficient is in the file: its bytes bound what was allocated.
        let start = self.cursor.at();
        let lattice = self.lattice()?;
        if let Err(detail) = admit(lattice.dims, lattice.coeffs.len() as u64) {
            self.cursor.rewind_to(start);
            return Err(self.error(&detail));
        }
        let dense = lattice.coeffs.dense_brick_count();
        if dense > max_dense {
            self.cursor.rewind_to(start);
            return Err(self.error(&too_many_dense(max_dense)));
        }
        Ok(lattice)
    }

    /// A lattice stored as brick records (see the module documentation). The header is
    /// checked, and its dims by `admit`, before anything is allocated: the directory (one
    /// entry per brick) is then bounded by the budget `admit` enforces, and each dense brick
    /// by the bytes that hold its values.
    fn bricked_lattice(
        &mut self,
        max_dense: usize,
        admit: impl FnOnce([usize; 3], u64) -> Result<(), String>,
    ) -> Result<BSplineLattice, SessionError> {
        let start = self.cursor.at();
        let dims = [
            self.u32()? as usize,
            self.u32()? as usize,
            self.u32()? as usize,
        ];
        let spacing = self.f32()?;
        let origin = self.vec3()?;
        let iso = self.f32()?;
        let bricks_at = self.cursor.at();
        let bricks = self.u64()?;
        let refuse = |r: &mut Self, at: usize, detail: &str| {
            r.cursor.rewind_to(at);
            r.error(detail)
        };
        if !(origin.is_finite() && iso.is_finite()) {
            return Err(refuse(
                self,
                start,
                "lattice origin or iso-level is not finite",
            ));
        }
        if !(spacing.is_finite() && spacing > 0.0) {
            return Err(refuse(
                self,
                start,
                &format!("lattice spacing {spacing}: must be finite and above 0"),
            ));
        }
        if dims.iter().any(|&n| n < 4) {
            return Err(refuse(
                self,
                start,
                &format!("lattice {dims:?}: every axis needs at least 4 coefficients"),
            ));
        }
        let Some(count) = dims
            .iter()
            .try_fold(1_u64, |acc, &d| acc.checked_mul(d as u64))
        else {
            return Err(refuse(
                self,
                start,
                &format!("lattice {dims:?}: its coefficient count overflows"),
            ));
        };
        if let Err(detail) = admit(dims, count) {
            return Err(refuse(self, start, &detail));
        }
        let expected: u64 = dims
            .iter()
            .map(|&n| n.div_ceil(COEFF_BRICK) as u64)
            .product();
        if bricks != expected {
            return Err(refuse(
                self,
                bricks_at,
                &format!("lattice {dims:?} has {expected} bricks; the section says {bricks}"),
            ));
        }
        let [nx, ny, _] = dims;
        let mut read = 0_u64;
        let mut run_left = 0_u32;
        let mut run_value = 0.0_f32;
        let built = BrickedCoeffs::try_from_owned_bricks(
            dims,
            max_dense,
            |first, extent, out| -> Result<Option<f32>, SessionError> {
                read += 1;
                if run_left > 0 {
                    run_left -= 1;
                    return Ok(Some(run_value));
                }
                let at = self.cursor.at();
                match self.u8()? {
                    UNIFORM_RUN => {
                        let length = self.u32()?;
                        let left = expected - read + 1;
                        if length == 0 || u64::from(length) > left {
                            return Err(refuse(
                                self,
                                at,
                                &format!(
                                    "a run of {length} uniform bricks from coefficient {first:?}; \
                                 {left} bricks are left in the lattice"
                                ),
                            ));
                        }
                        let value_at = self.cursor.at();
                        let value = self.f32()?;
                        if !value.is_finite() {
                            return Err(refuse(
                                self,
                                value_at,
                                &format!(
                                    "the uniform bricks from coefficient {first:?} hold {value}, \
                                 not a finite number"
                                ),
                            ));
                        }
                        run_left = length - 1;
                        run_value = value;
                        Ok(Some(value))
                    }
                    DENSE_BRICK => {
                        let values_at = self.cursor.at();
                        let raw = self.take(4 * out.len())?;
                        for (v, b) in out.iter_mut().zip(raw.chunks_exact(4)) {
                            *v = f32::from_le_bytes(b.try_into().expect("4 bytes"));
                        }
                        if let Some(n) = out.iter().position(|v| !v.is_finite()) {
                            let local = [
                                n % extent[0],
                                (n / extent[0]) % extent[1],
                                n / (extent[0] * extent[1]),
                            ];
                            let [i, j, k] = std::array::from_fn(|a| first[a] + local[a]);
                            let flat = i + nx * (j + ny * k);
                            return Err(refuse(
                                self,
                                values_at + 4 * n,
                                &format!(
                                    "lattice coefficient {flat} is {}, not a finite number",
                                    out[n]
                                ),
                            ));
                        }
                        Ok(None)
                    }
                    tag => Err(refuse(
                        self,
                        at,
                        &format!(
                            "brick record {tag}; a record is {UNIFORM_RUN} (a run of uniform \
                         bricks) or {DENSE_BRICK} (a dense brick)"
                        ),
                    )),
                }
            },
        );
        let coeffs = match built {
            Ok(coeffs) => coeffs,
            Err(OwnedBricksError::Fill(e)) => return Err(e),
            Err(OwnedBricksError::TooManyDense { max_dense }) => {
                return Err(refuse(self, start, &too_many_dense(max_dense)));
            }
        };
        Ok(BSplineLattice {
            dims,
            spacing,
            origin,
            iso,
            coeffs,
        })
    }

    /// A patch map `T_i` (see [`put_map`]): finite and invertible, with a finite inverse.
    fn map(&mut self) -> Result<Affine3A, SessionError> {
        let start = self.cursor.at();
        let mut cols = [0.0_f32; 12];
        for c in &mut cols {
            *c = self.f32()?;
        }
        let map = Affine3A::from_cols_array(&cols);
        let det = map.matrix3.determinant();
        if !(map.is_finite() && det.is_finite() && det.abs() > 1e-12 && map.inverse().is_finite()) {
            self.cursor.rewind_to(start);
            return Err(self.error(&format!(
                "the patch's map to patch space is not finite and invertible (determinant {det})"
            )));
        }
        // A patch is drawn and simulated on grids sized in world space: a map that shrinks or
        // stretches it by more than MAX_MAP_SCALE would size them beyond any machine.
        let inverse = map.matrix3.inverse();
        let stretch = [map.matrix3, inverse]
            .iter()
            .flat_map(|m| [m.x_axis, m.y_axis, m.z_axis])
            .map(|c| c.length())
            .fold(0.0_f32, f32::max);
        if stretch > MAX_MAP_SCALE {
            self.cursor.rewind_to(start);
            return Err(self.error(&format!(
                "the patch's map scales by {stretch:.3e}; at most {MAX_MAP_SCALE} either way"
            )));
        }
        Ok(map)
    }

    /// Every byte of the payload must have been read.
    fn finish(&self) -> Result<(), SessionError> {
        if self.cursor.remaining() == 0 {
            Ok(())
        } else {
            Err(self.error(&format!(
                "{} unread bytes at the end of the section",
                self.cursor.remaining()
            )))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::MultiPatchField;
    use crate::tools::{Clay, StampParams};

    pub(crate) fn sample_session() -> Session {
        let mut patch = BSplineLattice::zeros([9, 8, 7], 0.25, Vec3::new(-1.0, -1.0, 0.5)).unwrap();
        patch.coeffs.update_each(|n, c| {
            *c = ((n * 31) % 17) as f32 / 17.0;
        });
        patch.iso = 0.45;
        let mut colour = ColourField::matching(&patch).unwrap();
        colour.channels[1].coeffs.set_flat(5, 0.75);
        let mut tool_lattice = BSplineLattice::zeros([5, 5, 5], 0.1, Vec3::ZERO).unwrap();
        tool_lattice.coeffs.set_flat(62, 1.0);
        Session {
            clay: Clay {
                density: MultiPatchField {
                    patches: vec![
                        Patch::identity(patch.clone()),
                        Patch {
                            lattice: patch,
                            world_to_patch: Affine3A::from_scale_rotation_translation(
                                Vec3::splat(2.0),
                                glam::Quat::from_rotation_z(0.3),
                                Vec3::new(0.5, -0.25, 1.0),
                            ),
                        },
                    ],
                },
                colour: Some(colour),
                constraints: vec![
                    Constraint::Point {
                        at: Vec3::new(0.1, 0.2, 0.3),
                    },
                    Constraint::Curve {
                        points: vec![Vec3::ZERO, Vec3::ONE],
                    },
                    Constraint::Normal {
                        at: Vec3::ONE,
                        normal: Vec3::Z,
                    },
                ],
                mask: None,
            },
            material: MaterialFields {
                uniform: Material::PLASTIC,
                grids: vec![MaterialGrid {
                    name: "stiffness".into(),
                    dims: [2, 2, 2],
                    values: vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0],
                }],
            },
            tools: vec![
                ToolPreset {
                    name: "ball".into(),
                    shape: ToolShape::Sphere { radius_fu: 0.2 },
                    action: ToolAction::Add {
                        deposit_rate_per_s: 3.0,
                    },
                    falloff_fu: 0.05,
                },
                ToolPreset {
                    name: "seal".into(),
                    shape: ToolShape::Freeform(FreeformTool {
                        lattice: tool_lattice,
                        scale: Vec3::new(1.0, 2.0, 0.5),
                    }),
                    action: ToolAction::Stamp(StampParams::default()),
                    falloff_fu: 0.0,
                },
                ToolPreset {
                    name: "scraper".into(),
                    shape: ToolShape::Profiled {
                        radius_fu: 0.15,
                        curve: crate::tools::FalloffCurve::Custom(vec![
                            [0.0, 0.6],
                            [0.8, 0.5],
                            [1.0, 0.0],
                        ]),
                    },
                    action: ToolAction::Remove,
                    falloff_fu: 0.1,
                },
            ],
            meta: SessionMeta {
                name: "test".into(),
                created_unix_s: 1,
                saved_unix_s: 2,
                writer: "dynaclay test".into(),
            },
        }
    }

    #[test]
    fn empty_files_version_zero_and_no_sections_say_what_is_wrong() {
        let p = Path::new("bad.dclay");
        let empty = decode(&[], p).unwrap_err().to_string();
        assert!(
            empty.contains("bad.dclay") && empty.contains("empty"),
            "{empty}"
        );
        let good = encode(&sample_session()).unwrap();
        let with_header = |at: usize, value: u32| {
            let mut b = good.clone();
            b[at..at + 4].copy_from_slice(&value.to_le_bytes());
            let crc = crc32fast::hash(&b[..20]);
            b[20..24].copy_from_slice(&crc.to_le_bytes());
            b
        };
        let v0 = decode(&with_header(8, 0), p).unwrap_err().to_string();
        assert!(
            v0.contains("version 0") && !v0.contains("newer") && v0.contains("byte 8"),
            "{v0}"
        );
        let none = decode(&with_header(12, 0), p).unwrap_err().to_string();
        assert!(
            none.contains("section count is 0") && !none.contains("truncated"),
            "{none}"
        );
    }

    #[test]
    fn round_trip_is_exact() {
        let s = sample_session();
        let bytes = encode(&s).unwrap();
        let back = decode(&bytes, Path::new("mem")).unwrap();
        assert_eq!(back, s);
    }

    #[test]
    fn every_single_byte_flip_is_rejected() {
        let bytes = encode(&sample_session()).unwrap();
        // Flip one bit in every byte position; none may load.
        for pos in 0..bytes.len() {
            let mut bad = bytes.clone();
            bad[pos] ^= 0x10;
            assert!(
                decode(&bad, Path::new("mem")).is_err(),
                "flip at {pos} accepted"
            );
        }
    }

    #[test]
    fn every_truncation_is_rejected_with_a_named_section() {
        let bytes = encode(&sample_session()).unwrap();
        for len in 0..bytes.len() {
            let err = decode(&bytes[..len], Path::new("cut.dclay")).unwrap_err();
            let text = err.to_string();
            assert!(text.starts_with("cut.dclay"), "{text}");
            if len >= 8 {
                assert!(
                    matches!(err, SessionError::Truncated { .. }),
                    "length {len}: {text}"
                );
            }
        }
    }

    #[test]
    fn foreign_and_future_files_are_named_as_such() {
        let err = decode(b"PK\x03\x04 a zip file, not ours", Path::new("x.zip")).unwrap_err();
        assert!(matches!(err, SessionError::NotASession { .. }), "{err}");
        let mut bytes = encode(&sample_session()).unwrap();
        bytes[8..12].copy_from_slice(&(FORMAT_VERSION + 1).to_le_bytes());
        let crc = crc32fast::hash(&bytes[..20]);
        bytes[20..24].copy_from_slice(&crc.to_le_bytes());
        let err = decode(&bytes, Path::new("new.dclay")).unwrap_err();
        assert!(
            matches!(err, SessionError::UnsupportedVersion { found, .. } if found == FORMAT_VERSION + 1),
            "{err}"
        );
    }

    #[test]
    fn a_non_finite_coefficient_under_a_valid_checksum_is_refused_at_its_offset() {
        let s = sample_session();
        // Version 3: every coefficient after the 40-byte lattice header; version 4: the first
        // brick's record (its tag byte, then its own coefficients: coefficient 3 is the
        // fourth of its first row).
        for (version, record) in [(3, 0), (BRICKED_VERSION, 1)] {
            let mut bytes = encode_version(&s, version).unwrap();
            let meta_len = serde_json::to_vec(&s.meta).unwrap().len();
            let first_patch = HEADER_LEN + (16 + meta_len);
            if version == BRICKED_VERSION {
                assert_eq!(bytes[first_patch + 12 + 40], DENSE_BRICK);
            }
            let at = first_patch + 12 + 40 + record + 4 * 3;
            bytes[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
            let len =
                u64::from_le_bytes(bytes[first_patch + 4..first_patch + 12].try_into().unwrap());
            let end = first_patch + 12 + len as usize;
            let crc = crc32fast::hash(&bytes[first_patch..end]);
            bytes[end..end + 4].copy_from_slice(&crc.to_le_bytes());
            let err = decode(&bytes, Path::new("mem")).unwrap_err().to_string();
            assert!(err.contains("coefficient 3"), "version {version}: {err}");
            assert!(
                err.contains(&format!("{at}")),
                "names the byte offset {at}: {err}"
            );
        }
    }

    #[test]
    fn a_corrupt_payload_names_its_section_and_offset() {
        let s = sample_session();
        let bytes = encode(&s).unwrap();
        // Corrupt a coefficient in the second patch section.
        let meta_len = serde_json::to_vec(&s.meta).unwrap().len();
        // A patch section: its 16 framing bytes, the lattice (its 40-byte header and two dense
        // bricks: a tag and 8 × 8 × 7 own coefficients, a tag and 1 × 8 × 7) and its map (48).
        let records = (1 + 4 * 8 * 8 * 7) + (1 + 4 * 8 * 7);
        let second_patch = HEADER_LEN + (16 + meta_len) + (16 + 40 + records + 48);
        assert_eq!(sections(&bytes)[2], (PATCH, second_patch));
        let mut bad = bytes.clone();
        bad[second_patch + 12 + 60] ^= 1;
        match decode(&bad, Path::new("mem")).unwrap_err() {
            SessionError::Checksum {
                section, offset, ..
            } => {
                assert_eq!(section, "PTCH (#2)");
                assert_eq!(offset, second_patch as u64);
            }
            other => panic!("{other}"),
        }
    }

    #[test]
    fn pins_are_written_only_when_present_and_a_bad_pin_is_named() {
        let mut session = sample_session();
        assert!(!session.clay.constraints.is_empty());
        let with = encode(&session).unwrap();
        assert!(with.windows(4).any(|w| w == PINS));
        assert_eq!(decode(&with, Path::new("p.dclay")).unwrap(), session);
        // Without pins the file is what older builds wrote, and reads back with none.
        session.clay.constraints.clear();
        let without = encode(&session).unwrap();
        assert!(!without.windows(4).any(|w| w == PINS));
        assert!(
            decode(&without, Path::new("old.dclay"))
                .unwrap()
                .clay
                .constraints
                .is_empty()
        );
        // A curve of one point under a valid checksum is refused, naming the section.
        session.clay.constraints = vec![Constraint::Curve {
            points: vec![Vec3::ZERO],
        }];
        let bad = encode(&session).unwrap();
        let err = decode(&bad, Path::new("bad.dclay"))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("PINS") && err.contains("constraint 0"),
            "{err}"
        );
    }

    #[test]
    fn the_spring_neighbourhood_round_trips_and_old_files_read_as_six() {
        let mut session = sample_session();
        let path = Path::new("springs.dclay");
        // Six (the default): no SPRG section, the bytes older builds wrote.
        let six = encode(&session).unwrap();
        assert!(!six.windows(4).any(|w| w == SPRINGS));
        let back = decode(&six, path).unwrap();
        assert_eq!(back.material.uniform.neighbourhood, Neighbourhood::Six);
        for nb in [Neighbourhood::Eighteen, Neighbourhood::TwentySix] {
            session.material.uniform.neighbourhood = nb;
            let bytes = encode(&session).unwrap();
            assert!(bytes.windows(4).any(|w| w == SPRINGS));
            assert_eq!(decode(&bytes, path).unwrap(), session);
        }
        // A count that is no neighbourhood is refused, naming the section.
        let mut bytes = encode(&session).unwrap();
        let at = bytes.windows(4).position(|w| w == SPRINGS).unwrap();
        bytes[at + 12..at + 16].copy_from_slice(&12_u32.to_le_bytes());
        let crc = crc32fast::hash(&bytes[at..at + 16]);
        bytes[at + 16..at + 20].copy_from_slice(&crc.to_le_bytes());
        let err = decode(&bytes, path).unwrap_err().to_string();
        assert!(err.contains("SPRG") && err.contains("12"), "{err}");
    }

    #[test]
    fn patch_maps_round_trip_and_version_1_files_read_with_identity_maps() {
        let session = sample_session();
        let path = Path::new("maps.dclay");
        let back = decode(&encode(&session).unwrap(), path).unwrap();
        assert_eq!(back.clay.density, session.clay.density);
        let old = decode(&encode_version(&session, 1).unwrap(), path).unwrap();
        assert_eq!(old.clay.density.patches.len(), 2);
        for (old, new) in old
            .clay
            .density
            .patches
            .iter()
            .zip(&session.clay.density.patches)
        {
            assert_eq!(old.lattice, new.lattice);
            assert_eq!(old.world_to_patch, Affine3A::IDENTITY);
        }
    }

    #[test]
    fn a_freeze_mask_round_trips_and_older_files_read_with_none() {
        let mut session = sample_session();
        let mut mask = FreezeMask::matching(&session.clay.density).unwrap();
        mask.patches[0].coeffs.set_flat(7, 1.0);
        mask.patches[1].coeffs.set_flat(3, 0.25);
        session.clay.mask = Some(mask);
        let path = Path::new("mask.dclay");
        let back = decode(&encode(&session).unwrap(), path).unwrap();
        assert_eq!(back.clay.mask, session.clay.mask);
        assert_eq!(back.clay.density, session.clay.density);
        // A version 2 file holds no mask and reads without one.
        let old = decode(&encode_version(&session, 2).unwrap(), path).unwrap();
        assert!(old.clay.mask.is_none());
        assert_eq!(old.clay.density, session.clay.density);
        // A hold out of range is refused, naming the section and the patch.
        session.clay.mask.as_mut().unwrap().patches[1]
            .coeffs
            .set_flat(3, 1.5);
        let err = decode(&encode(&session).unwrap(), path)
            .unwrap_err()
            .to_string();
        assert!(err.contains("MASK") && err.contains("patch 1"), "{err}");
        // A mask that does not fit its patch is refused.
        let mask = session.clay.mask.as_mut().unwrap();
        mask.patches[1] = BSplineLattice::zeros([4, 4, 4], 0.1, Vec3::ZERO).unwrap();
        let err = decode(&encode(&session).unwrap(), path)
            .unwrap_err()
            .to_string();
        assert!(err.contains("MASK") && err.contains("dims"), "{err}");
    }

    #[test]
    fn a_singular_patch_map_is_refused_with_its_offset() {
        let mut session = sample_session();
        session.clay.density.patches[1]
            .world_to_patch
            .matrix3
            .z_axis = glam::Vec3A::ZERO;
        let err = decode(&encode(&session).unwrap(), Path::new("flat.dclay"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("PTCH") && err.contains("invertible"), "{err}");
    }
    /// Every section's tag and the byte it starts at.
    fn sections(bytes: &[u8]) -> Vec<([u8; 4], usize)> {
        let mut out = Vec::new();
        let mut pos = HEADER_LEN;
        while pos + 12 <= bytes.len() {
            let tag: [u8; 4] = bytes[pos..pos + 4].try_into().unwrap();
            let len = u64::from_le_bytes(bytes[pos + 4..pos + 12].try_into().unwrap()) as usize;
            out.push((tag, pos));
            pos += 12 + len + 4;
        }
        out
    }

    /// `bytes` with the payload of section `index` replaced by `payload`, its length and
    /// checksum made to match (what a hostile writer can do).
    fn with_payload(bytes: &[u8], index: usize, payload: &[u8]) -> Vec<u8> {
        let (tag, pos) = sections(bytes)[index];
        let len = u64::from_le_bytes(bytes[pos + 4..pos + 12].try_into().unwrap()) as usize;
        let mut out = bytes[..pos].to_vec();
        out.extend_from_slice(&tag);
        out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
        out.extend_from_slice(payload);
        let crc = crc32fast::hash(&out[pos..]);
        out.extend_from_slice(&crc.to_le_bytes());
        out.extend_from_slice(&bytes[pos + 12 + len + 4..]);
        out
    }

    /// A lattice header of format 4 (dims, spacing, origin, iso, brick count).
    fn bricked_header(dims: [u32; 3], bricks: u64) -> Vec<u8> {
        let mut out = Vec::new();
        for d in dims {
            out.extend_from_slice(&d.to_le_bytes());
        }
        for v in [0.1_f32, 0.0, 0.0, 0.0, 0.5] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&bricks.to_le_bytes());
        out
    }

    fn run_record(bricks: u32, value: f32) -> Vec<u8> {
        let mut out = vec![UNIFORM_RUN];
        out.extend_from_slice(&bricks.to_le_bytes());
        out.extend_from_slice(&value.to_le_bytes());
        out
    }

    /// A ball of clay: density 1 inside, 0 outside, a band of a few knot spans between, so
    /// the bricks far from the surface are uniform and those near it dense.
    fn ball(dims: [usize; 3], spacing: f32) -> BSplineLattice {
        let mut l = BSplineLattice::zeros(dims, spacing, Vec3::ZERO).unwrap();
        let centre = Vec3::from_array(dims.map(|n| n as f32)) * spacing * 0.5;
        let radius = 0.35 * dims[0] as f32 * spacing;
        let [nx, ny, _] = dims;
        l.coeffs.update_each(|n, c| {
            let at = Vec3::new(
                (n % nx) as f32,
                ((n / nx) % ny) as f32,
                (n / (nx * ny)) as f32,
            ) * spacing;
            *c = ((radius - at.distance(centre)) / (3.0 * spacing) + 0.5).clamp(0.0, 1.0);
        });
        l
    }

    /// A sculpted clay: a ball, a stroke removed from the base, a detail patch refined over
    /// part of it with a lump added there, paint over another part, a freeze mask and pins.
    fn sculpted_session() -> Session {
        use crate::tools::{ApplyOptions, GeometricTool, ToolPose, apply_tool};
        let mut clay = Clay::single(ball([40, 36, 44], 0.1));
        let top = Vec3::new(2.0, 1.8, 2.2 + 0.35 * 4.0);
        let tool = |shape, action| GeometricTool {
            shape,
            action,
            falloff_fu: 0.15,
        };
        let remove = tool(ToolShape::Sphere { radius_fu: 0.4 }, ToolAction::Remove);
        for k in 0..4 {
            let at = top + Vec3::new(0.2 * k as f32, 0.0, 0.0);
            apply_tool(
                &mut clay,
                &remove,
                &ToolPose::at(at),
                1.0,
                &ApplyOptions::default(),
                None,
            )
            .unwrap();
        }
        let side = Vec3::new(2.0 + 0.35 * 4.0, 1.8, 2.2);
        let detail = clay
            .density
            .refine(side - Vec3::splat(0.5), side + Vec3::splat(0.5), 2)
            .unwrap();
        let add = tool(
            ToolShape::Sphere { radius_fu: 0.2 },
            ToolAction::Add {
                deposit_rate_per_s: 2.0,
            },
        );
        let options = ApplyOptions {
            patch: u16::try_from(detail).unwrap(),
            ..ApplyOptions::default()
        };
        apply_tool(&mut clay, &add, &ToolPose::at(side), 0.5, &options, None).unwrap();
        let paint = tool(
            ToolShape::Sphere { radius_fu: 0.5 },
            ToolAction::Paint {
                rgb: [0.8, 0.2, 0.1],
            },
        );
        let front = Vec3::new(2.0, 1.8 - 0.35 * 3.6, 2.2);
        apply_tool(
            &mut clay,
            &paint,
            &ToolPose::at(front),
            1.0,
            &ApplyOptions::default(),
            None,
        )
        .unwrap();
        let mut mask = FreezeMask::matching(&clay.density).unwrap();
        for n in 0..mask.patches[0].coeffs.len() {
            if n % 40 < 12 {
                mask.patches[0].coeffs.set_flat(n, 1.0);
            }
        }
        mask.patches[1].coeffs.set_flat(17, 0.5);
        clay.mask = Some(mask);
        clay.constraints = sample_session().clay.constraints;
        Session {
            clay,
            ..sample_session()
        }
    }

    /// Every lattice of the clay, in the order the file holds them.
    fn clay_lattices(clay: &Clay) -> Vec<&BSplineLattice> {
        let density = clay.density.patches.iter().map(|p| &p.lattice);
        let colour = clay.colour.iter().flat_map(|c| c.channels.iter());
        let mask = clay.mask.iter().flat_map(|m| m.patches.iter());
        density.chain(colour).chain(mask).collect()
    }

    #[test]
    fn a_sculpted_multi_patch_clay_round_trips_coefficient_by_coefficient() {
        let s = sculpted_session();
        assert!(s.clay.colour.is_some() && s.clay.mask.is_some());
        assert_eq!(s.clay.density.patches.len(), 2);
        let base = &s.clay.density.patches[0].lattice.coeffs;
        assert!(
            base.dense_brick_count() > 0 && base.dense_brick_count() < base.brick_count(),
            "the base holds uniform and dense bricks: {base:?}"
        );
        let path = Path::new("sculpted.dclay");
        for version in [3, BRICKED_VERSION] {
            let back = decode(&encode_version(&s, version).unwrap(), path).unwrap();
            assert_eq!(back, s, "version {version}");
            let (saved, loaded) = (clay_lattices(&s.clay), clay_lattices(&back.clay));
            assert_eq!(saved.len(), 2 + 4 + 2);
            assert_eq!(saved.len(), loaded.len());
            for (n, (a, b)) in saved.iter().zip(&loaded).enumerate() {
                assert_eq!(
                    (a.dims, a.spacing, a.origin, a.iso),
                    (b.dims, b.spacing, b.origin, b.iso)
                );
                for (c, (x, y)) in a.coeffs.iter().zip(b.coeffs.iter()).enumerate() {
                    assert_eq!(x.to_bits(), y.to_bits(), "lattice {n} coefficient {c}");
                }
                // Nothing is denser than what was saved.
                assert!(b.coeffs.dense_brick_count() <= a.coeffs.dense_brick_count());
            }
            for (a, b) in s
                .clay
                .density
                .patches
                .iter()
                .zip(&back.clay.density.patches)
            {
                assert_eq!(a.world_to_patch, b.world_to_patch);
            }
            assert_eq!(back.clay.constraints, s.clay.constraints);
            assert_eq!(back.clay.mask, s.clay.mask);
            assert_eq!(back.clay.colour, s.clay.colour);
            // The loaded clay samples as the saved one does (the aprons were rebuilt).
            for k in 0..20 {
                let x = Vec3::new(0.3 + 0.17 * k as f32, 1.8, 0.4 + 0.19 * k as f32);
                assert_eq!(
                    back.clay.density.value_and_gradient(x),
                    s.clay.density.value_and_gradient(x)
                );
            }
        }
    }

    #[test]
    fn a_large_mostly_uniform_clay_is_much_smaller_in_version_4() {
        let s = Session {
            clay: Clay::single(ball([128, 128, 128], 0.05)),
            ..Session::default()
        };
        let v3 = encode_version(&s, 3).unwrap().len();
        let v4 = encode(&s).unwrap().len();
        // Version 3 holds every coefficient; version 4 only the bricks near the surface.
        assert!(v3 > 4 * 128 * 128 * 128, "{v3}");
        let ratio = v3 as f64 / v4 as f64;
        assert!(ratio > 5.0, "version 3: {v3} bytes, version 4: {v4} bytes");
        assert_eq!(
            decode(&encode(&s).unwrap(), Path::new("ball.dclay")).unwrap(),
            s
        );
    }

    /// The session of `core/src/io/testdata/session_v3.dclay`: two patches (one under a
    /// turned, scaled map), colour, pins, a freeze mask, a material grid and three tools.
    fn version_3_fixture_session() -> Session {
        let mut s = sample_session();
        let mut mask = FreezeMask::matching(&s.clay.density).unwrap();
        mask.patches[0].coeffs.set_flat(7, 1.0);
        mask.patches[1].coeffs.set_flat(3, 0.25);
        s.clay.mask = Some(mask);
        s
    }

    const VERSION_3_FIXTURE: &[u8] = include_bytes!("testdata/session_v3.dclay");

    /// Writes the fixture again (run by hand: `cargo test -p dynaclay-core --lib
    /// write_the_version_3_fixture -- --ignored`); a version 3 file must never change.
    #[test]
    #[ignore = "writes core/src/io/testdata/session_v3.dclay"]
    fn write_the_version_3_fixture() {
        let bytes = encode_version(&version_3_fixture_session(), 3).unwrap();
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("src/io/testdata/session_v3.dclay");
        std::fs::write(path, bytes).unwrap();
    }

    #[test]
    fn a_version_3_file_written_by_an_older_build_still_loads() {
        assert_eq!(
            u32::from_le_bytes(VERSION_3_FIXTURE[8..12].try_into().unwrap()),
            3
        );
        let back = decode(VERSION_3_FIXTURE, Path::new("session_v3.dclay")).unwrap();
        assert_eq!(back, version_3_fixture_session());
        // Saved again it is a version 4 file that reads back the same.
        let again = encode(&back).unwrap();
        assert_eq!(
            u32::from_le_bytes(again[8..12].try_into().unwrap()),
            FORMAT_VERSION
        );
        assert_eq!(decode(&again, Path::new("again.dclay")).unwrap(), back);
    }

    #[test]
    fn hostile_lattice_headers_are_refused_before_anything_is_allocated() {
        let good = encode(&sample_session()).unwrap();
        let path = Path::new("hostile.dclay");
        assert_eq!(sections(&good)[1].0, PATCH);
        let refused = |payload: Vec<u8>| -> String {
            match decode(&with_payload(&good, 1, &payload), path) {
                Err(e @ SessionError::Malformed { .. }) => e.to_string(),
                other => panic!("{other:?}"),
            }
        };
        // 2^60 coefficients in one run of uniform bricks: over the clay's budget.
        let huge = [1_u32 << 20; 3];
        let mut payload = bricked_header(huge, 1 << 51);
        payload.extend(run_record(u32::MAX, 1.0));
        let err = refused(payload);
        assert!(
            err.contains("PTCH") && err.contains(&format!("at most {MAX_CLAY_BOX_COEFFS}")),
            "{err}"
        );
        // A coefficient count that overflows.
        let err = refused(bricked_header([u32::MAX; 3], 0));
        assert!(err.contains("overflows"), "{err}");
        // A brick count that is not the dims'.
        let err = refused(bricked_header([16, 16, 16], 9));
        assert!(
            err.contains("has 8 bricks") && err.contains("says 9"),
            "{err}"
        );
        // A run longer than the bricks left.
        let mut payload = bricked_header([16, 16, 16], 8);
        payload.extend(run_record(3, 0.0));
        payload.extend(run_record(6, 1.0));
        let err = refused(payload);
        assert!(
            err.contains("run of 6") && err.contains("5 bricks are left"),
            "{err}"
        );
        // A run of no bricks, a non-finite value and an unknown record.
        let mut payload = bricked_header([16, 16, 16], 8);
        payload.extend(run_record(0, 0.0));
        assert!(refused(payload).contains("run of 0"));
        let mut payload = bricked_header([16, 16, 16], 8);
        payload.extend(run_record(8, f32::INFINITY));
        assert!(refused(payload).contains("not a finite number"));
        let mut payload = bricked_header([16, 16, 16], 8);
        payload.push(7);
        assert!(refused(payload).contains("brick record 7"));
        // A dense brick whose values the section does not hold.
        let mut payload = bricked_header([16, 16, 16], 8);
        payload.push(DENSE_BRICK);
        payload.extend_from_slice(&[0; 64]);
        let err = refused(payload);
        assert!(err.contains("needs 2048 more bytes"), "{err}");
        // A colour channel over the budget.
        let colour = sections(&good)
            .iter()
            .position(|(t, _)| *t == COLOUR)
            .unwrap();
        let mut payload = bricked_header(huge, 1 << 51);
        payload.extend(run_record(u32::MAX, 0.0));
        let err = decode(&with_payload(&good, colour, &payload), path)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("COLR") && err.contains("colour channel"),
            "{err}"
        );
    }

    #[test]
    fn a_mask_of_other_dims_is_refused_before_its_bricks_are_read() {
        let s = version_3_fixture_session();
        let good = encode(&s).unwrap();
        let mask = sections(&good)
            .iter()
            .position(|(t, _)| *t == MASK)
            .unwrap();
        let mut payload = 2_u32.to_le_bytes().to_vec();
        // A mask over patch 0 of 2^40 coefficients, then nothing.
        payload.extend(bricked_header([1 << 20, 1 << 20, 4], 1 << 34));
        let err = decode(&with_payload(&good, mask, &payload), Path::new("m.dclay"))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("MASK") && err.contains("patch 0") && err.contains("dims"),
            "{err}"
        );
    }

    #[test]
    fn only_the_versions_this_build_reads_are_written() {
        let s = sample_session();
        for version in [0, FORMAT_VERSION + 1] {
            let err = encode_version(&s, version).unwrap_err().to_string();
            assert!(err.contains(&format!("format version {version}")), "{err}");
        }
        for version in 1..=FORMAT_VERSION {
            let bytes = encode_version(&s, version).unwrap();
            assert_eq!(
                u32::from_le_bytes(bytes[8..12].try_into().unwrap()),
                version
            );
            decode(&bytes, Path::new("v.dclay")).unwrap();
        }
    }

    #[test]
    fn a_clay_at_the_edge_of_the_box_budget_saves_and_loads() {
        // One patch of exactly MAX_CLAY_BOX_COEFFS coefficients (a 1024³ box of empty space
        // and a small ball): its directory is 32 MiB and its file small; refine and growth
        // admit it, so loading must.
        let dims = [1024, 1024, 1024];
        assert_eq!(dims.iter().product::<usize>(), MAX_CLAY_BOX_COEFFS);
        let mut l = BSplineLattice::zeros(dims, 0.01, Vec3::ZERO).unwrap();
        for n in 0..64 {
            l.coeffs
                .set(250 + n % 4, 250 + (n / 4) % 4, 120 + n / 16, 1.0);
        }
        let dense = l.coeffs.dense_brick_count();
        let s = Session {
            clay: Clay::single(l),
            ..Session::default()
        };
        let bytes = encode(&s).unwrap();
        assert!(bytes.len() < 1 << 20, "{} bytes", bytes.len());
        let back = decode(&bytes, Path::new("edge.dclay")).unwrap();
        let (a, b) = (&s.clay.base().coeffs, &back.clay.base().coeffs);
        assert_eq!(b.dims(), dims);
        assert_eq!(b.dense_brick_count(), dense);
        for n in 0..64 {
            let at = [250 + n % 4, 250 + (n / 4) % 4, 120 + n / 16];
            assert_eq!(b.get(at[0], at[1], at[2]), 1.0);
        }
        let sample = |c: &BrickedCoeffs| c.box_summary([240, 240, 110], [270, 270, 140], true);
        assert_eq!(sample(a), sample(b));
        assert_eq!(sample(b).max, 1.0);
        // One more coefficient of detail would not load, nor would it refine.
        let mut over = s;
        let tiny = BSplineLattice::zeros([4, 4, 4], 0.001, Vec3::ZERO).unwrap();
        over.clay.density.push(tiny, Affine3A::IDENTITY);
        let err = decode(&encode(&over).unwrap(), Path::new("over.dclay"))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains(&format!("at most {MAX_CLAY_BOX_COEFFS}")),
            "{err}"
        );
    }

    /// A clay of `bricks` dense bricks in a base of 64³ coefficients (one changed value per
    /// brick, away from every apron), with a colour field whose red channel holds one more.
    fn clay_of_dense_bricks(bricks: usize) -> Clay {
        let mut l = BSplineLattice::zeros([64; 3], 0.05, Vec3::ZERO).unwrap();
        for n in 0..bricks {
            let [i, j, k] = [n % 8, (n / 8) % 8, n / 64].map(|b| 8 * b + 5);
            l.coeffs.set(i, j, k, 0.5);
        }
        let mut colour = ColourField::matching(&l).unwrap();
        colour.channels[0].coeffs.set(13, 13, 13, 0.25);
        let mut clay = Clay::single(l);
        clay.colour = Some(colour);
        clay
    }

    #[test]
    fn a_clay_at_the_edge_of_the_dense_budget_saves_and_loads_and_one_over_is_refused() {
        for version in [3, BRICKED_VERSION] {
            let clay = clay_of_dense_bricks(40);
            assert_eq!(clay.dense_brick_count(), 41);
            let s = Session {
                clay,
                ..Session::default()
            };
            let bytes = encode_version(&s, version).unwrap();
            let path = Path::new("dense.dclay");
            // At the edge: exactly the bricks it holds.
            let back = decode_within(&bytes, path, 41).unwrap();
            assert_eq!(back, s, "version {version}");
            assert_eq!(back.clay.dense_brick_count(), 41);
            // One brick fewer in the budget: the colour channel that needs it is refused.
            let err = decode_within(&bytes, path, 40).unwrap_err();
            let text = err.to_string();
            assert!(
                matches!(err, SessionError::Malformed { .. })
                    && text.contains("COLR")
                    && text.contains("more than the 0 dense bricks"),
                "version {version}: {text}"
            );
            // Fewer still: the patch itself.
            let text = decode_within(&bytes, path, 39).unwrap_err().to_string();
            assert!(
                text.contains("PTCH") && text.contains("more than the 39 dense bricks"),
                "version {version}: {text}"
            );
        }
    }

    #[test]
    fn a_hostile_file_of_uniform_bricks_cannot_make_dense_bricks_past_the_budget() {
        // Every brick uniform, alternating 0 and 1 along x: each brick's apron reaches a
        // neighbour of the other value, so loading would make nearly every brick dense.
        let dims = [64, 64, 64];
        let small = Session {
            clay: Clay::single(BSplineLattice::zeros([8; 3], 0.1, Vec3::ZERO).unwrap()),
            ..Session::default()
        };
        let good = encode(&small).unwrap();
        assert_eq!(sections(&good)[1].0, PATCH);
        let mut payload = bricked_header(dims, 512);
        for n in 0..512_u32 {
            payload.extend(run_record(1, (n % 2) as f32));
        }
        for v in Affine3A::IDENTITY.to_cols_array() {
            payload.extend_from_slice(&v.to_le_bytes());
        }
        let bytes = with_payload(&good, 1, &payload);
        let path = Path::new("stripes.dclay");
        let all = decode(&bytes, path);
        // Accepted whole under the real budget (448 bricks have an apron) …
        let clay = all.map(|s| s.clay).unwrap();
        assert_eq!(clay.base().coeffs.dense_brick_count(), 448);
        // … and refused, before the brick past it is allocated, under a smaller one.
        let text = decode_within(&bytes, path, 100).unwrap_err().to_string();
        assert!(text.contains("more than the 100 dense bricks"), "{text}");
    }
}
