//! The JSON messages of Haply's Inverse Service on its simulation channel (a WebSocket, by
//! default `ws://localhost:10001`), as the service documents them:
//!
//! - On connect the service sends one full snapshot; after that it sends exactly one state
//!   message for each message it receives, so the client's sends set the cadence.
//! - A state message is an object whose `inverse3` array holds one entry per arm:
//!   `{"device_id": "049D", "config": {...}, "state": {"cursor_position": {"x","y","z"},
//!   "cursor_velocity": {"x","y","z"}, ...}}` (`config` only in the first snapshot), metres and
//!   metres per second in Haply's frame: +x right, +y forward (away from the user), +z up.
//!   A VerseGrip handle, when paired, appears in `wireless_verse_grip` (or `verse_grip`) with
//!   `state.buttons` `{"a","b","c"}` booleans.
//! - The force command is `{"inverse3": [{"device_id": ID, "commands": {"set_cursor_force":
//!   {"values": {"x","y","z"}}}}]}`, newtons in the same frame.
//!
//! [`parse_state`] bounds the message before it parses anything ([`MAX_MESSAGE_BYTES`]) and
//! names the field and the byte of every fault; [`encode_force`] writes the command into a
//! caller's buffer. Both allocate (serde_json's value tree, the string), so they run on the
//! driver's I/O thread, never on the haptic tick.

use std::fmt::Write as _;

use glam::Vec3;
use serde_json::Value;

/// Where the service listens by default (its simulation channel).
pub const DEFAULT_SERVICE_URL: &str = "ws://localhost:10001";

/// Largest message accepted from the service, bytes. A full snapshot of a few devices is a few
/// kilobytes; anything near this bound is not the service.
pub const MAX_MESSAGE_BYTES: usize = 256 * 1024;

/// Longest device id accepted, bytes (the service's are four hex digits).
pub const MAX_DEVICE_ID_BYTES: usize = 64;

/// What a state message says about one Inverse3 (and the handle's buttons, if one is paired).
#[derive(Clone, Debug, PartialEq)]
pub struct Inverse3Report {
    /// The arm's id, as the force command must name it.
    pub device_id: String,
    /// Cursor position, metres, Haply's frame.
    pub cursor_position_m: [f64; 3],
    /// Cursor velocity, metres per second, Haply's frame.
    pub cursor_velocity_m_per_s: [f64; 3],
    /// Buttons of a paired VerseGrip: bit 0 `a`, bit 1 `b`, bit 2 `c` (0 without a handle).
    pub buttons: u32,
    /// `config.basis.permutation`, when the message carries the configuration.
    pub basis_permutation: Option<String>,
}

/// Why a message from the service was refused: what, and where.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ServiceMessageError {
    /// The message is longer than [`MAX_MESSAGE_BYTES`].
    #[error("message of {bytes} bytes is longer than the {max} allowed")]
    TooLarge {
        /// Its length.
        bytes: usize,
        /// The bound.
        max: usize,
    },
    /// A binary WebSocket message where JSON text was expected.
    #[error("binary message of {bytes} bytes where JSON text was expected")]
    Binary {
        /// Its length.
        bytes: usize,
    },
    /// The text is not JSON.
    #[error("not JSON at byte {offset} (line {line}, column {column}): {reason}")]
    NotJson {
        /// Byte offset of the fault.
        offset: usize,
        /// Line of the fault (from 1).
        line: usize,
        /// Column of the fault (from 1).
        column: usize,
        /// The parser's words.
        reason: String,
    },
    /// A field is missing.
    #[error("field `{path}` is missing")]
    Missing {
        /// Its path, e.g. `inverse3[0].state.cursor_position.y`.
        path: String,
    },
    /// A field has the wrong type.
    #[error("field `{path}` is not {expected}")]
    WrongType {
        /// Its path.
        path: String,
        /// What it should be.
        expected: &'static str,
    },
    /// A number is not finite (or out of the f64 range).
    #[error("field `{path}` is not a finite number")]
    NotFinite {
        /// Its path.
        path: String,
    },
    /// The message lists no Inverse3 at all.
    #[error("the service lists no Inverse3 (its `inverse3` array is empty)")]
    NoInverse3,
    /// The arm this session drives is no longer listed.
    #[error("Inverse3 `{device_id}` is no longer listed by the service")]
    DeviceGone {
        /// The arm's id.
        device_id: String,
    },
    /// A device id longer than [`MAX_DEVICE_ID_BYTES`].
    #[error("field `{path}` is {bytes} bytes long, more than the {max} allowed for a device id")]
    DeviceIdTooLong {
        /// Its path.
        path: String,
        /// Its length.
        bytes: usize,
        /// The bound.
        max: usize,
    },
}

impl ServiceMessageError {
    /// A fixed description of the fault (for [`crate::DeviceError::Protocol`], which carries
    /// no heap data).
    #[must_use]
    pub fn what(&self) -> &'static str {
        match self {
            Self::TooLarge { .. } => "Inverse Service message too large",
            Self::Binary { .. } => "Inverse Service sent a binary message",
            Self::NotJson { .. } => "Inverse Service message is not JSON",
            Self::Missing { .. } => "Inverse Service message lacks a field",
            Self::WrongType { .. } => "Inverse Service message field of the wrong type",
            Self::NotFinite { .. } => "Inverse Service message number not finite",
            Self::NoInverse3 => "Inverse Service lists no Inverse3",
            Self::DeviceGone { .. } => "Inverse3 no longer listed by the service",
            Self::DeviceIdTooLong { .. } => "Inverse Service device id too long",
        }
    }

    /// The byte offset of the fault in the message (0 where the fault is not at one byte).
    #[must_use]
    pub fn offset(&self) -> usize {
        match self {
            Self::NotJson { offset, .. } => *offset,
            Self::TooLarge { max, .. } => *max,
            _ => 0,
        }
    }
}

/// Byte offset of 1-based `line` and `column` in `text`.
fn byte_offset(text: &str, line: usize, column: usize) -> usize {
    let line_start: usize = text
        .split_inclusive('\n')
        .take(line.saturating_sub(1))
        .map(str::len)
        .sum();
    (line_start + column.saturating_sub(1)).min(text.len())
}

fn field<'a>(v: &'a Value, key: &str, path: &str) -> Result<&'a Value, ServiceMessageError> {
    v.get(key).ok_or_else(|| ServiceMessageError::Missing {
        path: format!("{path}.{key}"),
    })
}

fn object<'a>(v: &'a Value, path: &str) -> Result<&'a Value, ServiceMessageError> {
    if v.is_object() {
        Ok(v)
    } else {
        Err(ServiceMessageError::WrongType {
            path: path.to_string(),
            expected: "an object",
        })
    }
}

fn number(v: &Value, path: &str) -> Result<f64, ServiceMessageError> {
    let x = v.as_f64().ok_or_else(|| ServiceMessageError::WrongType {
        path: path.to_string(),
        expected: "a number",
    })?;
    if x.is_finite() {
        Ok(x)
    } else {
        Err(ServiceMessageError::NotFinite {
            path: path.to_string(),
        })
    }
}

fn vec3(v: &Value, path: &str) -> Result<[f64; 3], ServiceMessageError> {
    let v = object(v, path)?;
    let mut out = [0.0; 3];
    for (slot, axis) in out.iter_mut().zip(["x", "y", "z"]) {
        *slot = number(field(v, axis, path)?, &format!("{path}.{axis}"))?;
    }
    Ok(out)
}

fn device_id(entry: &Value, path: &str) -> Result<String, ServiceMessageError> {
    let p = format!("{path}.device_id");
    let id = field(entry, "device_id", path)?.as_str().ok_or_else(|| {
        ServiceMessageError::WrongType {
            path: p.clone(),
            expected: "a string",
        }
    })?;
    if id.len() > MAX_DEVICE_ID_BYTES {
        return Err(ServiceMessageError::DeviceIdTooLong {
            path: p,
            bytes: id.len(),
            max: MAX_DEVICE_ID_BYTES,
        });
    }
    Ok(id.to_string())
}

/// Buttons of the first paired handle (`wireless_verse_grip`, else `verse_grip`); 0 if none.
fn handle_buttons(root: &Value) -> Result<u32, ServiceMessageError> {
    for key in ["wireless_verse_grip", "verse_grip"] {
        let Some(list) = root.get(key) else { continue };
        let Some(first) = list.as_array().and_then(|a| a.first()) else {
            continue;
        };
        let Some(buttons) = first.get("state").and_then(|s| s.get("buttons")) else {
            continue;
        };
        let path = format!("{key}[0].state.buttons");
        let buttons = object(buttons, &path)?;
        let mut bits = 0;
        for (bit, name) in ["a", "b", "c"].into_iter().enumerate() {
            match buttons.get(name) {
                None | Some(Value::Bool(false)) => {}
                Some(Value::Bool(true)) => bits |= 1 << bit,
                Some(_) => {
                    return Err(ServiceMessageError::WrongType {
                        path: format!("{path}.{name}"),
                        expected: "a boolean",
                    });
                }
            }
        }
        return Ok(bits);
    }
    Ok(0)
}

/// Parses a state message (the first snapshot or any later one) and returns the report of the
/// arm `device_id`, or of the first listed arm when `device_id` is `None`.
///
/// # Errors
/// A [`ServiceMessageError`] naming the field (by its path) or the byte that is wrong; the
/// length is checked before anything is parsed.
pub fn parse_state(
    text: &str,
    device_id: Option<&str>,
) -> Result<Inverse3Report, ServiceMessageError> {
    if text.len() > MAX_MESSAGE_BYTES {
        return Err(ServiceMessageError::TooLarge {
            bytes: text.len(),
            max: MAX_MESSAGE_BYTES,
        });
    }
    let root: Value = serde_json::from_str(text).map_err(|e| ServiceMessageError::NotJson {
        offset: byte_offset(text, e.line(), e.column()),
        line: e.line(),
        column: e.column(),
        reason: e.to_string(),
    })?;
    let root = object(&root, "message")?;
    let list = root
        .get("inverse3")
        .ok_or_else(|| ServiceMessageError::Missing {
            path: "inverse3".into(),
        })?
        .as_array()
        .ok_or_else(|| ServiceMessageError::WrongType {
            path: "inverse3".into(),
            expected: "an array",
        })?;
    let mut chosen = None;
    for (i, entry) in list.iter().enumerate() {
        let path = format!("inverse3[{i}]");
        let entry = object(entry, &path)?;
        let id = self::device_id(entry, &path)?;
        if device_id.is_none_or(|want| want == id) {
            chosen = Some((path, entry, id));
            break;
        }
    }
    let Some((path, entry, id)) = chosen else {
        return Err(match device_id {
            None => ServiceMessageError::NoInverse3,
            Some(want) => ServiceMessageError::DeviceGone {
                device_id: want.to_string(),
            },
        });
    };
    let state_path = format!("{path}.state");
    let state = object(field(entry, "state", &path)?, &state_path)?;
    let cursor_position_m = vec3(
        field(state, "cursor_position", &state_path)?,
        &format!("{state_path}.cursor_position"),
    )?;
    let cursor_velocity_m_per_s = vec3(
        field(state, "cursor_velocity", &state_path)?,
        &format!("{state_path}.cursor_velocity"),
    )?;
    let basis_permutation = match entry
        .get("config")
        .and_then(|c| c.get("basis"))
        .and_then(|b| b.get("permutation"))
    {
        None => None,
        Some(Value::String(s)) => Some(s.clone()),
        Some(_) => {
            return Err(ServiceMessageError::WrongType {
                path: format!("{path}.config.basis.permutation"),
                expected: "a string",
            });
        }
    };
    Ok(Inverse3Report {
        device_id: id,
        cursor_position_m,
        cursor_velocity_m_per_s,
        buttons: handle_buttons(root)?,
        basis_permutation,
    })
}

/// The device id as a JSON string literal (quotes and escapes included), made once at open so
/// [`encode_force`] can splice it in.
#[must_use]
pub fn quoted_device_id(device_id: &str) -> String {
    Value::String(device_id.to_string()).to_string()
}

/// Writes the `set_cursor_force` command for the arm whose quoted id is `quoted_id` (see
/// [`quoted_device_id`]) into `out` (cleared first), newtons in Haply's frame. A non-finite
/// component is sent as zero.
pub fn encode_force(quoted_id: &str, force_n: [f64; 3], out: &mut String) {
    let f = force_n.map(|c| if c.is_finite() { c } else { 0.0 });
    out.clear();
    // Writing to a String cannot fail.
    let _ = write!(
        out,
        r#"{{"inverse3":[{{"device_id":{quoted_id},"commands":{{"set_cursor_force":{{"values":{{"x":{},"y":{},"z":{}}}}}}}}}]}}"#,
        f[0], f[1], f[2]
    );
}

/// Haply's frame (+x right, +y away from the user, +z up) to the device frame (+x right, +y
/// up, +z toward the user): a rotation, no mirror.
#[must_use]
pub fn haply_to_device(v: [f64; 3]) -> Vec3 {
    Vec3::new(v[0] as f32, v[2] as f32, -v[1] as f32)
}

/// The device frame to Haply's.
#[must_use]
pub fn device_to_haply(v: Vec3) -> [f64; 3] {
    [f64::from(v.x), -f64::from(v.z), f64::from(v.y)]
}

#[cfg(test)]
mod tests {
    use super::*;

    const SNAPSHOT: &str = r#"{
 "session_id": 7,
 "inverse3": [{
  "device_id": "049D",
  "config": {"handedness": "right", "basis": {"permutation": "XYZ"}},
  "state": {
   "cursor_position": {"x": 0.01, "y": -0.12, "z": 0.15},
   "cursor_velocity": {"x": 0.0, "y": 0.5, "z": -0.25}
  }
 }],
 "wireless_verse_grip": [{"device_id": "0A1", "state": {"buttons": {"a": false, "b": true, "c": true}}}]
}"#;

    #[test]
    fn the_documented_snapshot_parses() {
        let r = parse_state(SNAPSHOT, None).unwrap();
        assert_eq!(r.device_id, "049D");
        assert_eq!(r.cursor_position_m, [0.01, -0.12, 0.15]);
        assert_eq!(r.cursor_velocity_m_per_s, [0.0, 0.5, -0.25]);
        assert_eq!(r.buttons, 0b110);
        assert_eq!(r.basis_permutation.as_deref(), Some("XYZ"));
        assert_eq!(parse_state(SNAPSHOT, Some("049D")).unwrap(), r);
    }

    #[test]
    fn faults_name_the_field_or_the_byte() {
        let e = parse_state(&SNAPSHOT.replace("\"y\": -0.12", "\"y\": \"no\""), None).unwrap_err();
        assert_eq!(
            e,
            ServiceMessageError::WrongType {
                path: "inverse3[0].state.cursor_position.y".into(),
                expected: "a number"
            }
        );
        let e = parse_state(&SNAPSHOT.replace("\"cursor_velocity\"", "\"v\""), None).unwrap_err();
        assert!(
            e.to_string()
                .contains("`inverse3[0].state.cursor_velocity` is missing"),
            "{e}"
        );
        let text = "{\"inverse3\": [}";
        match parse_state(text, None).unwrap_err() {
            ServiceMessageError::NotJson { offset, line, .. } => {
                assert_eq!((offset, line), (14, 1));
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(
            parse_state(r#"{"inverse3": []}"#, None).unwrap_err(),
            ServiceMessageError::NoInverse3
        );
        assert_eq!(
            parse_state(SNAPSHOT, Some("1111")).unwrap_err(),
            ServiceMessageError::DeviceGone {
                device_id: "1111".into()
            }
        );
        let long = " ".repeat(MAX_MESSAGE_BYTES + 1);
        assert!(matches!(
            parse_state(&long, None).unwrap_err(),
            ServiceMessageError::TooLarge { .. }
        ));
        let id = "x".repeat(MAX_DEVICE_ID_BYTES + 1);
        let e = parse_state(&SNAPSHOT.replace("049D", &id), None).unwrap_err();
        assert!(
            matches!(e, ServiceMessageError::DeviceIdTooLong { .. }),
            "{e}"
        );
        let e = parse_state(&SNAPSHOT.replace("\"b\": true", "\"b\": 1"), None).unwrap_err();
        assert!(
            e.to_string()
                .contains("wireless_verse_grip[0].state.buttons.b"),
            "{e}"
        );
        // A number past f64's range is refused by the parser itself, with its place.
        assert!(parse_state(&SNAPSHOT.replace("0.15", "1e999"), None).is_err());
    }

    #[test]
    fn the_force_command_round_trips_through_a_json_parser() {
        let mut out = String::new();
        encode_force(
            &quoted_device_id("04\"9D"),
            [1.5, -0.25, f64::NAN],
            &mut out,
        );
        let v: Value = serde_json::from_str(&out).unwrap();
        let cmd = &v["inverse3"][0];
        assert_eq!(cmd["device_id"], "04\"9D");
        let values = &cmd["commands"]["set_cursor_force"]["values"];
        assert_eq!(values["x"], 1.5);
        assert_eq!(values["y"], -0.25);
        assert_eq!(values["z"], 0.0);
    }

    #[test]
    fn frames_rotate_without_a_mirror() {
        // Right stays right, Haply's up is the device's up, forward is away from the user.
        assert_eq!(haply_to_device([1.0, 0.0, 0.0]), Vec3::X);
        assert_eq!(haply_to_device([0.0, 0.0, 1.0]), Vec3::Y);
        assert_eq!(haply_to_device([0.0, 1.0, 0.0]), -Vec3::Z);
        let v = Vec3::new(0.1, -0.2, 0.3);
        assert_eq!(haply_to_device(device_to_haply(v)), v);
        let x = haply_to_device([1.0, 0.0, 0.0]);
        let y = haply_to_device([0.0, 1.0, 0.0]);
        let z = haply_to_device([0.0, 0.0, 1.0]);
        assert!((x.cross(y).dot(z) - 1.0).abs() < 1e-6, "right-handed");
    }
}
