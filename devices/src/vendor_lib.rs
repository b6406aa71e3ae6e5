//! Finding and loading a vendor's haptic library at run time (OpenHaptics' `libHD.so`, Force
//! Dimension's `libdhd.so`), as CHAI3D does: dynaclay neither links against nor ships them.
//!
//! Where a library is looked for, in order: the path in its environment variable
//! ([`VendorLibrary::env_var`]) or a path given in the driver options, and then only there;
//! otherwise the dynamic loader's search (`LD_LIBRARY_PATH`, the ld.so cache) by the vendor's
//! file names, then the install folders the vendors' Linux packages use. When none loads, the
//! typed [`LibraryMissing`] lists every candidate tried with the loader's reason, names the
//! variable to set, and says how to install the library.
//!
//! Loading happens in `open` only; nothing here runs on the haptic path.

use std::fmt;
use std::path::{Path, PathBuf};

use libloading::Library;

/// A vendor library dynaclay can drive an arm through.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VendorLibrary {
    /// OpenHaptics' HD API: 3D Systems Touch, Touch X, Phantom Omni, Desktop and Premium.
    OpenHapticsHd,
    /// Force Dimension's DHD API: omega, delta, sigma and lambda arms, and the Novint Falcon.
    ForceDimensionDhd,
}

impl VendorLibrary {
    /// Every vendor library, in the order `dynaclay devices` reports them.
    pub const ALL: [Self; 2] = [Self::OpenHapticsHd, Self::ForceDimensionDhd];

    /// What the library is, for messages: e.g. `"OpenHaptics HD library (libHD.so)"`.
    #[must_use]
    pub fn label(self) -> &'static str {
        match self {
            Self::OpenHapticsHd => "OpenHaptics HD library (libHD.so)",
            Self::ForceDimensionDhd => "Force Dimension DHD library (libdhd.so)",
        }
    }

    /// The environment variable that names the library's path explicitly.
    #[must_use]
    pub fn env_var(self) -> &'static str {
        match self {
            Self::OpenHapticsHd => "DYNACLAY_HD_LIB",
            Self::ForceDimensionDhd => "DYNACLAY_DHD_LIB",
        }
    }

    /// The `--device` spec that opens an arm through this library.
    #[must_use]
    pub fn spec(self) -> &'static str {
        match self {
            Self::OpenHapticsHd => "touch",
            Self::ForceDimensionDhd => "dhd",
        }
    }

    /// Names handed to the dynamic loader's own search, in order.
    #[must_use]
    pub fn loader_names(self) -> &'static [&'static str] {
        match self {
            Self::OpenHapticsHd => &["libHD.so", "libHD.so.3"],
            Self::ForceDimensionDhd => &["libdhd.so", "libdhd.so.3"],
        }
    }

    /// Install locations tried after the loader's search (where the vendors' Linux packages
    /// and their install instructions put the library).
    #[must_use]
    pub fn install_paths(self) -> &'static [&'static str] {
        match self {
            Self::OpenHapticsHd => &[
                "/usr/lib/libHD.so",
                "/usr/lib64/libHD.so",
                "/usr/local/lib/libHD.so",
                "/opt/OpenHaptics/Developer/lib/libHD.so",
            ],
            Self::ForceDimensionDhd => &[
                "/usr/local/lib/libdhd.so",
                "/usr/lib/libdhd.so",
                "/opt/forcedimension/lib/libdhd.so",
            ],
        }
    }

    /// How to install the library.
    #[must_use]
    pub fn install_hint(self) -> &'static str {
        match self {
            Self::OpenHapticsHd => {
                "install \"OpenHaptics for Linux (Developer Edition)\" and the Touch device \
                 driver from 3D Systems' support site (support.3dsystems.com), run Touch_Setup \
                 to configure the arm, or set DYNACLAY_HD_LIB to the path of libHD.so"
            }
            Self::ForceDimensionDhd => {
                "install the Force Dimension SDK for Linux (forcedimension.com, Downloads) and \
                 put its lib folder on LD_LIBRARY_PATH, or set DYNACLAY_DHD_LIB to the path of \
                 libdhd.so"
            }
        }
    }
}

/// Where to look for a vendor library.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum LibrarySource {
    /// The environment variable if set, else the loader's search and the install paths.
    #[default]
    Search,
    /// Exactly this file (a stand-in, a copy outside the usual places).
    Path(PathBuf),
}

/// One place a library was looked for, and why it did not load from there.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TriedCandidate {
    /// A path, or a bare file name handed to the loader's search.
    pub candidate: String,
    /// The loader's message, or the missing symbol.
    pub reason: String,
}

/// A vendor library could not be loaded: which, where it was looked for, and how to get it.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "{} not loaded; tried {}; {}",
    library.label(),
    Tried(tried),
    library.install_hint()
)]
pub struct LibraryMissing {
    /// The library looked for.
    pub library: VendorLibrary,
    /// Every candidate tried, in order, with the reason it failed.
    pub tried: Vec<TriedCandidate>,
}

/// The candidates of a [`LibraryMissing`], `; `-separated.
struct Tried<'a>(&'a [TriedCandidate]);

impl fmt::Display for Tried<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, t) in self.0.iter().enumerate() {
            if i > 0 {
                f.write_str(", ")?;
            }
            write!(f, "{} ({})", t.candidate, t.reason)?;
        }
        Ok(())
    }
}

/// A loaded vendor library and where it came from.
pub struct LoadedLibrary {
    /// The open library; symbols taken from it are valid while it lives.
    pub library: Library,
    /// The candidate it was loaded from (a path or a loader name).
    pub from: String,
}

/// The candidates for `library` from `source`, in the order they are tried: the explicit path
/// or environment variable alone when given, else loader names then install paths.
#[must_use]
pub fn candidates(library: VendorLibrary, source: &LibrarySource) -> Vec<String> {
    match source {
        LibrarySource::Path(p) => vec![p.display().to_string()],
        LibrarySource::Search => match std::env::var_os(library.env_var()) {
            Some(p) if !p.is_empty() => vec![Path::new(&p).display().to_string()],
            _ => library
                .loader_names()
                .iter()
                .chain(library.install_paths())
                .map(|s| (*s).to_string())
                .collect(),
        },
    }
}

/// Loads `library` from the first candidate that opens and exports `required_symbol`.
///
/// # Errors
/// [`LibraryMissing`] listing every candidate and why it failed.
pub fn load(
    library: VendorLibrary,
    source: &LibrarySource,
    required_symbol: &str,
) -> Result<LoadedLibrary, LibraryMissing> {
    let mut tried = Vec::new();
    let explicit = matches!(source, LibrarySource::Path(_))
        || std::env::var_os(library.env_var()).is_some_and(|p| !p.is_empty());
    for candidate in candidates(library, source) {
        // An explicit path is loaded as given; install paths that do not exist are noted
        // without asking the loader (its message would only say the same).
        if !explicit && candidate.starts_with('/') && !Path::new(&candidate).exists() {
            tried.push(TriedCandidate {
                candidate,
                reason: "no such file".into(),
            });
            continue;
        }
        // SAFETY: loading a shared library runs its initialisers. The candidates are the
        // vendor's own library names and install paths, or a path the user named for exactly
        // this library; dynaclay trusts them as it trusts its own dependencies.
        match unsafe { Library::new(&candidate) } {
            Ok(lib) => {
                // SAFETY: only the symbol's presence is checked; the pointer is not used.
                let found = unsafe { lib.get::<*const ()>(required_symbol.as_bytes()) };
                if found.is_ok() {
                    return Ok(LoadedLibrary {
                        library: lib,
                        from: candidate,
                    });
                }
                tried.push(TriedCandidate {
                    candidate,
                    reason: format!("loaded, but it has no symbol `{required_symbol}`"),
                });
            }
            Err(e) => tried.push(TriedCandidate {
                candidate,
                // libloading shows dlerror's own text.
                reason: e.to_string(),
            }),
        }
    }
    if !explicit {
        tried.insert(
            0,
            TriedCandidate {
                candidate: format!("${}", library.env_var()),
                reason: "not set".into(),
            },
        );
    }
    Err(LibraryMissing { library, tried })
}

/// Whether each vendor library can be loaded from where [`load`] would look, for
/// `dynaclay devices`: `Ok(from)` names where it was found.
#[must_use]
pub fn probe_all() -> Vec<(VendorLibrary, Result<String, LibraryMissing>)> {
    VendorLibrary::ALL
        .iter()
        .map(|&lib| {
            let symbol = match lib {
                VendorLibrary::OpenHapticsHd => "hdInitDevice",
                VendorLibrary::ForceDimensionDhd => "dhdGetDeviceCount",
            };
            (
                lib,
                load(lib, &LibrarySource::Search, symbol).map(|l| l.from),
            )
        })
        .collect()
}

/// Takes the function `name` from `lib` as a plain function pointer.
///
/// # Safety
/// `F` must be an `unsafe extern "C" fn` type matching the C declaration of `name` exactly,
/// and the pointer must not be called after `lib` is dropped.
pub(crate) unsafe fn function<F: Copy>(
    lib: &LoadedLibrary,
    name: &'static str,
) -> Result<F, TriedCandidate> {
    // SAFETY: the caller promises F matches the symbol's C signature.
    match unsafe { lib.library.get::<F>(name.as_bytes()) } {
        Ok(symbol) => Ok(*symbol),
        Err(_) => Err(TriedCandidate {
            candidate: lib.from.clone(),
            reason: format!("loaded, but it has no symbol `{name}`"),
        }),
    }
}

/// Takes the function `name` from `lib` if it exports it (newer SDK releases add functions).
///
/// # Safety
/// As [`function`].
pub(crate) unsafe fn optional_function<F: Copy>(
    lib: &LoadedLibrary,
    name: &'static str,
) -> Option<F> {
    // SAFETY: as the caller promises for `function`.
    unsafe { function(lib, name) }.ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_explicit_path_is_the_only_candidate() {
        let source = LibrarySource::Path("/nowhere/libHD.so".into());
        assert_eq!(
            candidates(VendorLibrary::OpenHapticsHd, &source),
            vec!["/nowhere/libHD.so".to_string()]
        );
    }

    #[test]
    fn a_missing_library_names_the_library_each_candidate_and_the_cure() {
        let source = LibrarySource::Path("/nowhere/libdhd.so".into());
        let e = load(
            VendorLibrary::ForceDimensionDhd,
            &source,
            "dhdGetDeviceCount",
        )
        .err()
        .unwrap();
        assert_eq!(e.library, VendorLibrary::ForceDimensionDhd);
        assert_eq!(e.tried.len(), 1);
        assert_eq!(e.tried[0].candidate, "/nowhere/libdhd.so");
        let text = e.to_string();
        for needle in [
            "libdhd.so",
            "/nowhere/libdhd.so",
            "Force Dimension SDK",
            "DYNACLAY_DHD_LIB",
        ] {
            assert!(text.contains(needle), "{needle} missing from: {text}");
        }
        assert!(
            e.tried[0].reason.contains("No such file") || e.tried[0].reason.contains("cannot open"),
            "{}",
            e.tried[0].reason
        );
    }

    #[test]
    fn a_library_without_the_api_is_refused_naming_the_symbol() {
        // The C library is loaded in every Rust process and is certainly not libHD.
        let source = LibrarySource::Path("libc.so.6".into());
        let e = load(VendorLibrary::OpenHapticsHd, &source, "hdInitDevice")
            .err()
            .unwrap();
        assert_eq!(
            e.tried[0].reason,
            "loaded, but it has no symbol `hdInitDevice`"
        );
    }
}
