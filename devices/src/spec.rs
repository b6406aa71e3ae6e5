//! Device specs as typed on the command line (`--device`): `sim`, `hid[:PROFILE]`,
//! `serial:PATH[:PROFILE]`, `falcon:PATH`, `touch[:NAME]` (alias `phantom[:NAME]`), `dhd[:N]`,
//! `inverse3[:URL]`, `2diy:PATH[:v2|v3]`, `spacemouse`, `mouse`, `replay:FILE`.
//!
//! Parsing is pure and total: any string gives a [`DeviceSpec`] or a [`SpecError`] that quotes
//! the input and says what was expected; it never panics.

use std::fmt;
use std::path::PathBuf;
use std::str::FromStr;

use crate::two_diy::TwoDiyVersion;

/// Largest device index `dhd:N` accepts (DHD numbers devices with a signed char).
pub const MAX_DHD_INDEX: u8 = 127;

/// Which device to open.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum DeviceSpec {
    /// The simulated arm.
    Sim,
    /// A force-feedback arm over USB HID; profile name or file (default `woodenhaptics`).
    Hid {
        /// Built-in profile name or path to a profile TOML.
        profile: Option<String>,
    },
    /// A Cartesian arm on a serial port; profile default `cartesian-serial`.
    Serial {
        /// Serial port path.
        path: PathBuf,
        /// Built-in profile name or path to a profile TOML.
        profile: Option<String>,
    },
    /// A Novint Falcon on its FTDI serial port.
    Falcon {
        /// Serial port path.
        path: PathBuf,
    },
    /// A 3D Systems Touch / Phantom arm through OpenHaptics' HD library (`touch`, `phantom`).
    OpenHaptics {
        /// HD device configuration name (Touch_Setup's); `None` for the default device.
        device: Option<String>,
    },
    /// A Force Dimension arm (or a Falcon) through the DHD library (`dhd[:N]`).
    Dhd {
        /// Which connected device, counting from 0.
        index: u8,
    },
    /// A Haply Inverse3 through Haply's Inverse Service (`inverse3[:URL]`).
    Inverse3 {
        /// The service's WebSocket URL; `None` for its default, `ws://localhost:10001`.
        url: Option<String>,
    },
    /// A Haply 2DIY on a serial port (`2diy:PATH[:v2|v3]`, third generation by default).
    TwoDiy {
        /// Serial port path.
        path: PathBuf,
        /// Which generation.
        version: TwoDiyVersion,
    },
    /// A 3Dconnexion SpaceMouse (pose input, no force).
    SpaceMouse,
    /// The window's mouse or pen (`mouse`): the app aims it at the clay (pose input, no force).
    Pointer,
    /// Replay of a recorded session.
    Replay {
        /// Recording file.
        file: PathBuf,
    },
}

/// Why a device spec did not parse.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "invalid device `{input}`: {reason} (expected sim, hid[:PROFILE], serial:PATH[:PROFILE], falcon:PATH, touch[:NAME], phantom[:NAME], dhd[:N], inverse3[:URL], 2diy:PATH[:v2|v3], spacemouse, mouse or replay:FILE)",
    input = input.escape_debug()
)]
pub struct SpecError {
    /// The spec as given.
    pub input: String,
    /// What was wrong.
    pub reason: String,
}

impl FromStr for DeviceSpec {
    type Err = SpecError;

    fn from_str(s: &str) -> Result<Self, SpecError> {
        let err = |reason: &str| SpecError {
            input: s.to_string(),
            reason: reason.to_string(),
        };
        let (kind, rest) = match s.split_once(':') {
            Some((k, r)) => (k, Some(r)),
            None => (s, None),
        };
        let nonempty = |what: &str, v: Option<&str>| match v {
            Some(v) if !v.trim().is_empty() => Ok(v.to_string()),
            _ => Err(err(&format!("`{kind}` needs a {what} after the colon"))),
        };
        match kind.trim().to_ascii_lowercase().as_str() {
            "sim" if rest.is_none() => Ok(Self::Sim),
            "spacemouse" if rest.is_none() => Ok(Self::SpaceMouse),
            "mouse" if rest.is_none() => Ok(Self::Pointer),
            "sim" | "spacemouse" | "mouse" => Err(err(&format!("`{kind}` takes no argument"))),
            "hid" => match rest {
                None => Ok(Self::Hid { profile: None }),
                Some(p) => Ok(Self::Hid {
                    profile: Some(nonempty("profile name or file", Some(p))?),
                }),
            },
            "serial" => {
                let rest = nonempty("port path", rest)?;
                // PATH[:PROFILE]: the profile follows the last colon, if any.
                match rest.rsplit_once(':') {
                    Some((path, profile)) if !path.is_empty() && !profile.is_empty() => {
                        Ok(Self::Serial {
                            path: PathBuf::from(path),
                            profile: Some(profile.to_string()),
                        })
                    }
                    Some(_) => Err(err(
                        "`serial` needs PATH or PATH:PROFILE with both parts non-empty",
                    )),
                    None => Ok(Self::Serial {
                        path: PathBuf::from(rest),
                        profile: None,
                    }),
                }
            }
            "touch" | "phantom" => match rest {
                None => Ok(Self::OpenHaptics { device: None }),
                Some(n) => Ok(Self::OpenHaptics {
                    device: Some(nonempty("device configuration name", Some(n))?),
                }),
            },
            "dhd" => match rest {
                None => Ok(Self::Dhd { index: 0 }),
                Some(n) => match n.trim().parse::<u8>() {
                    Ok(index) if index <= MAX_DHD_INDEX => Ok(Self::Dhd { index }),
                    _ => Err(err(&format!(
                        "`dhd` needs a device index from 0 to {MAX_DHD_INDEX} after the colon, not `{}`",
                        n.escape_debug()
                    ))),
                },
            },
            "inverse3" => match rest {
                None => Ok(Self::Inverse3 { url: None }),
                Some(u) => {
                    let u = nonempty("ws:// URL of the Inverse Service", Some(u))?;
                    if u.starts_with("ws://") {
                        Ok(Self::Inverse3 { url: Some(u) })
                    } else {
                        Err(err(&format!(
                            "`inverse3` takes the Inverse Service's ws:// URL after the colon \
                             (e.g. ws://localhost:10001), not `{}`",
                            u.escape_debug()
                        )))
                    }
                }
            },
            "2diy" => {
                let rest = nonempty("port path", rest)?;
                let (path, version) = match rest.rsplit_once(':') {
                    Some((path, v)) if !path.is_empty() && v.eq_ignore_ascii_case("v2") => {
                        (path, TwoDiyVersion::V2)
                    }
                    Some((path, v)) if !path.is_empty() && v.eq_ignore_ascii_case("v3") => {
                        (path, TwoDiyVersion::V3)
                    }
                    _ => (rest.as_str(), TwoDiyVersion::V3),
                };
                Ok(Self::TwoDiy {
                    path: PathBuf::from(path),
                    version,
                })
            }
            "falcon" => Ok(Self::Falcon {
                path: PathBuf::from(nonempty("port path", rest)?),
            }),
            "replay" => Ok(Self::Replay {
                file: PathBuf::from(nonempty("recording file", rest)?),
            }),
            "" => Err(err("empty device kind")),
            other => Err(err(&format!(
                "unknown device kind `{}`",
                other.escape_debug()
            ))),
        }
    }
}

impl fmt::Display for DeviceSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Sim => write!(f, "sim"),
            Self::Hid { profile: None } => write!(f, "hid"),
            Self::Hid { profile: Some(p) } => write!(f, "hid:{p}"),
            Self::Serial {
                path,
                profile: None,
            } => write!(f, "serial:{}", path.display()),
            Self::Serial {
                path,
                profile: Some(p),
            } => write!(f, "serial:{}:{p}", path.display()),
            Self::Falcon { path } => write!(f, "falcon:{}", path.display()),
            Self::OpenHaptics { device: None } => write!(f, "touch"),
            Self::OpenHaptics { device: Some(n) } => write!(f, "touch:{n}"),
            Self::Dhd { index: 0 } => write!(f, "dhd"),
            Self::Dhd { index } => write!(f, "dhd:{index}"),
            Self::Inverse3 { url: None } => write!(f, "inverse3"),
            Self::Inverse3 { url: Some(u) } => write!(f, "inverse3:{u}"),
            Self::TwoDiy {
                path,
                version: TwoDiyVersion::V3,
            } => write!(f, "2diy:{}", path.display()),
            Self::TwoDiy { path, version } => {
                write!(f, "2diy:{}:{}", path.display(), version.label())
            }
            Self::SpaceMouse => write!(f, "spacemouse"),
            Self::Pointer => write!(f, "mouse"),
            Self::Replay { file } => write!(f, "replay:{}", file.display()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(s: &str) -> Result<DeviceSpec, SpecError> {
        s.parse()
    }

    #[test]
    fn every_form_parses() {
        assert_eq!(p("sim"), Ok(DeviceSpec::Sim));
        assert_eq!(p("SpaceMouse"), Ok(DeviceSpec::SpaceMouse));
        assert_eq!(p("hid"), Ok(DeviceSpec::Hid { profile: None }));
        assert_eq!(
            p("hid:polhem"),
            Ok(DeviceSpec::Hid {
                profile: Some("polhem".into())
            })
        );
        assert_eq!(
            p("serial:/dev/ttyACM0"),
            Ok(DeviceSpec::Serial {
                path: "/dev/ttyACM0".into(),
                profile: None
            })
        );
        assert_eq!(
            p("serial:/dev/ttyACM0:my-arm.toml"),
            Ok(DeviceSpec::Serial {
                path: "/dev/ttyACM0".into(),
                profile: Some("my-arm.toml".into())
            })
        );
        assert_eq!(
            p("falcon:/dev/ttyUSB0"),
            Ok(DeviceSpec::Falcon {
                path: "/dev/ttyUSB0".into()
            })
        );
        assert_eq!(
            p("replay:runs/a:b.dcrec"),
            Ok(DeviceSpec::Replay {
                file: "runs/a:b.dcrec".into()
            })
        );
    }

    #[test]
    fn display_round_trips() {
        for s in [
            "sim",
            "hid",
            "hid:x.toml",
            "serial:/dev/ttyS0",
            "serial:/dev/ttyS0:cartesian-serial",
            "falcon:/dev/ttyUSB1",
            "spacemouse",
            "replay:f.rec",
            "touch",
            "touch:Default Device",
            "dhd",
            "dhd:2",
            "inverse3",
            "inverse3:ws://127.0.0.1:10001",
            "2diy:/dev/ttyACM0",
            "2diy:/dev/ttyACM0:v2",
        ] {
            assert_eq!(p(s).unwrap().to_string(), s);
        }
    }

    #[test]
    fn errors_quote_the_input_and_say_what_is_missing() {
        let e = p("falcon").unwrap_err().to_string();
        assert!(e.contains("`falcon`") && e.contains("port path"), "{e}");
        let e = p("usb:3").unwrap_err().to_string();
        assert!(e.contains("unknown device kind `usb`"), "{e}");
        assert!(p("sim:1").unwrap_err().reason.contains("no argument"));
        assert!(p("serial:/dev/x:").is_err());
        assert!(p("serial::arm").is_err());
        assert!(p("hid:").is_err());
        assert!(p("").is_err());
        assert!(p("replay:  ").is_err());
        assert!(p("touch:").is_err());
        let e = p("dhd:x").unwrap_err().to_string();
        assert!(
            e.contains("`dhd` needs a device index") && e.contains("`x`"),
            "{e}"
        );
        assert!(p("dhd:128").is_err());
        assert!(p("dhd:-1").is_err());
    }

    #[test]
    fn haply_arms_parse_with_their_url_port_and_generation() {
        assert_eq!(p("inverse3"), Ok(DeviceSpec::Inverse3 { url: None }));
        assert_eq!(
            p("Inverse3:ws://localhost:10001"),
            Ok(DeviceSpec::Inverse3 {
                url: Some("ws://localhost:10001".into())
            })
        );
        let e = p("inverse3:localhost:10001").unwrap_err().to_string();
        assert!(
            e.contains("ws:// URL") && e.contains("`localhost:10001`"),
            "{e}"
        );
        assert!(p("inverse3:").is_err());
        assert_eq!(
            p("2diy:/dev/ttyACM0"),
            Ok(DeviceSpec::TwoDiy {
                path: "/dev/ttyACM0".into(),
                version: TwoDiyVersion::V3
            })
        );
        assert_eq!(
            p("2DIY:/dev/ttyACM1:V2"),
            Ok(DeviceSpec::TwoDiy {
                path: "/dev/ttyACM1".into(),
                version: TwoDiyVersion::V2
            })
        );
        assert!(p("2diy").unwrap_err().reason.contains("port path"));
        assert!(p("2diy:").is_err());
    }

    #[test]
    fn vendor_arms_parse_with_their_aliases() {
        assert_eq!(p("touch"), Ok(DeviceSpec::OpenHaptics { device: None }));
        assert_eq!(p("Phantom"), Ok(DeviceSpec::OpenHaptics { device: None }));
        assert_eq!(
            p("phantom:PHANToM 1"),
            Ok(DeviceSpec::OpenHaptics {
                device: Some("PHANToM 1".into())
            })
        );
        assert_eq!(p("dhd"), Ok(DeviceSpec::Dhd { index: 0 }));
        assert_eq!(p("dhd:3"), Ok(DeviceSpec::Dhd { index: 3 }));
        assert_eq!(p("dhd:0").unwrap().to_string(), "dhd");
    }
}
