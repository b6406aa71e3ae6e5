//! Malformed session files and scripts are refused with an error, never a panic.
//!
//! Session files: random byte changes to a valid file, with every checksum recomputed
//! afterwards so that the section decoders themselves see the garbage (a plain flip would
//! only ever exercise the checksum check). Scripts: random edits of the built-in script's
//! text, through the parser and the layout step.

use std::path::Path;

use dynaclay::dynamics::Material;
use dynaclay::engine::{DEFAULT_SCRIPT, ScriptPlan};
use dynaclay::field::BSplineLattice;
use dynaclay::io::{Session, ToolPreset, decode, encode, parse_script};
use dynaclay::tools::{Clay, ColourField, ToolAction, ToolShape};
use glam::Vec3;
use proptest::prelude::*;

/// A small session with every section: a patch, colour, material and a tool.
fn valid_session_bytes() -> Vec<u8> {
    let mut lattice = BSplineLattice::zeros([4, 5, 4], 0.25, Vec3::new(0.5, -1.0, 0.0)).unwrap();
    for (i, c) in lattice.coeffs.iter_mut().enumerate() {
        *c = (i as f32 * 0.3).sin();
    }
    let mut colour = ColourField::matching(&lattice).unwrap();
    colour.channels[3].coeffs.fill(0.5);
    let session = Session {
        clay: Clay {
            patches: vec![lattice],
            colour: Some(colour),
            constraints: Vec::new(),
        },
        tools: vec![ToolPreset {
            name: "blob".into(),
            shape: ToolShape::Sphere { radius_m: 0.2 },
            action: ToolAction::Paint {
                rgb: [0.2, 0.4, 0.6],
            },
            falloff_m: 0.1,
        }],
        ..Session::default()
    };
    encode(&session).expect("encodes")
}

/// Recomputes the header's and every reachable section's CRC in place (the layout is in
/// `src/io/format.rs`: a 24-byte header, then tag, u64 length, payload, CRC32).
fn refresh_checksums(bytes: &mut [u8]) {
    if bytes.len() < 24 {
        return;
    }
    let crc = crc32fast::hash(&bytes[..20]);
    bytes[20..24].copy_from_slice(&crc.to_le_bytes());
    let mut pos = 24;
    while pos + 12 <= bytes.len() {
        let len = u64::from_le_bytes(bytes[pos + 4..pos + 12].try_into().unwrap());
        let Some(end) = usize::try_from(len)
            .ok()
            .and_then(|l| (pos + 12).checked_add(l))
        else {
            return;
        };
        if end + 4 > bytes.len() {
            return;
        }
        let crc = crc32fast::hash(&bytes[pos..end]);
        bytes[end..end + 4].copy_from_slice(&crc.to_le_bytes());
        pos = end + 4;
    }
}

#[test]
fn the_fixture_itself_decodes() {
    let mut bytes = valid_session_bytes();
    refresh_checksums(&mut bytes);
    assert!(decode(&bytes, Path::new("fixture.dclay")).is_ok());
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2048, ..ProptestConfig::default() })]

    #[test]
    fn damaged_sessions_are_refused_or_load_whole(
        edits in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..6),
        cut in proptest::option::of(any::<prop::sample::Index>()),
    ) {
        let mut bytes = valid_session_bytes();
        for (at, value) in &edits {
            let i = at.index(bytes.len());
            bytes[i] = *value;
        }
        if let Some(at) = cut {
            bytes.truncate(at.index(bytes.len()));
        }
        refresh_checksums(&mut bytes);
        match decode(&bytes, Path::new("damaged.dclay")) {
            Err(e) => {
                let text = e.to_string();
                prop_assert!(text.contains("damaged.dclay"), "the error names the file: {text}");
            }
            // A change the format cannot tell from a real edit (a coefficient's value, say)
            // must still give a session that is whole: finite coefficients, a material that
            // can drive a step, and it encodes again.
            Ok(session) => {
                let lattices = session.clay.patches.iter().chain(
                    session.clay.colour.iter().flat_map(|c| c.channels.iter()),
                );
                for l in lattices {
                    prop_assert!(l.coeffs.iter().all(|c| c.is_finite()));
                }
                prop_assert!(session.material.uniform.validate().is_ok());
                prop_assert!(encode(&session).is_ok());
            }
        }
    }

    #[test]
    fn edited_scripts_are_refused_or_laid_out(
        edits in proptest::collection::vec((any::<prop::sample::Index>(), 0u8..3, "[ -~\n]{0,3}"), 1..4),
    ) {
        let mut text: Vec<char> = DEFAULT_SCRIPT.chars().collect();
        for (at, kind, insert) in &edits {
            let i = at.index(text.len().max(1)).min(text.len());
            match kind {
                0 => {
                    if i < text.len() {
                        text.remove(i);
                    }
                }
                1 => text.splice(i..i, insert.chars()).for_each(drop),
                _ => {
                    let end = (i + insert.len()).min(text.len());
                    text.splice(i..end, insert.chars()).for_each(drop);
                }
            }
        }
        let text: String = text.into_iter().collect();
        match parse_script(&text, "edited.toml") {
            Err(e) => prop_assert!(e.to_string().starts_with("edited.toml"), "{e}"),
            Ok(script) => {
                if let Err(e) = ScriptPlan::new(&script, "edited.toml", Path::new("."), &[], Material::PLASTIC) {
                    prop_assert!(e.to_string().starts_with("edited.toml"), "{e}");
                }
            }
        }
    }
}
