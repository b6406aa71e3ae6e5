//! The one rule every output of every command and script step obeys, checked before any work
//! starts:
//! - an output is never one of the command's inputs, nor the running script;
//! - it replaces only a regular file of its own kind (a `.ply` point set may replace a `.ply`
//!   point set this program wrote, never a `.toml`, a `.txt` or a mesh), never a link, a
//!   directory or a device;
//! - its real path (every link on the way resolved) stays inside the allowed folders, unless
//!   the user lifted that with `--allow-outside`.
//!
//! Paths are compared by their real location, so `./a.ply`, `dir/../a.ply` and a link to
//! `a.ply` are all the same file.

use std::fs;
use std::io::Read;
use std::path::{Component, Path, PathBuf};

/// The kinds of file the program writes; each knows its extensions and how a file it wrote
/// begins.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutputKind {
    /// A session (`.dclay`).
    Session,
    /// A triangle mesh (`.obj`, `.ply` or `.stl`).
    Mesh,
    /// A point set with normals (`.ply`).
    PointSet,
    /// Particles with normals as XYZ text (`.xyz`).
    Particles,
    /// A compact RBF (`.rbf`).
    Rbf,
    /// A PNG image (`.png`).
    Image,
    /// A device recording (`--record`; any extension).
    Recording,
}

impl OutputKind {
    /// What the kind is called in messages.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Self::Session => "a session",
            Self::Mesh => "a mesh",
            Self::PointSet => "a point set",
            Self::Particles => "particles",
            Self::Rbf => "an RBF",
            Self::Image => "a PNG image",
            Self::Recording => "a device recording",
        }
    }

    /// The extensions an output of this kind may have (lower case, without the dot; none
    /// listed: any).
    #[must_use]
    pub const fn extensions(self) -> &'static [&'static str] {
        match self {
            Self::Session => &["dclay"],
            Self::Mesh => &["obj", "ply", "stl"],
            Self::PointSet => &["ply"],
            Self::Particles => &["xyz"],
            Self::Rbf => &["rbf"],
            Self::Image => &["png"],
            Self::Recording => &[],
        }
    }

    /// Whether a file beginning with `head` (its first [`HEAD_BYTES`] bytes, or all of a
    /// shorter file) is one this program wrote as this kind.
    fn wrote(self, head: &[u8]) -> bool {
        match self {
            Self::Session => head.starts_with(&super::format::MAGIC),
            Self::Rbf => head.starts_with(b"DCLYRBF\0"),
            Self::Image => head.starts_with(b"\x89PNG\r\n\x1a\n"),
            Self::Recording => head.starts_with(&dynaclay_devices::record::format::MAGIC),
            Self::PointSet => {
                head.starts_with(b"ply\n") && contains(head, b"comment dynaclay point set")
            }
            Self::Mesh => {
                head.starts_with(b"# dynaclay mesh")
                    || (head.starts_with(b"ply\n") && contains(head, b"comment dynaclay mesh"))
                    || head.starts_with(b"dynaclay mesh (binary STL)")
            }
            // Plain text of six numbers a line (an empty file: no particles).
            Self::Particles => std::str::from_utf8(head).is_ok_and(|text| {
                text.lines().take(1).all(|line| {
                    let fields: Vec<&str> = line.split_whitespace().collect();
                    fields.len() == 6 && fields.iter().all(|f| f.parse::<f32>().is_ok())
                })
            }),
        }
    }
}

/// How much of an existing file is read to tell what wrote it.
pub const HEAD_BYTES: usize = 256;

fn contains(hay: &[u8], needle: &[u8]) -> bool {
    hay.windows(needle.len()).any(|w| w == needle)
}

/// Why an output was refused: what, where, and which flag or step asked for it.
#[derive(Debug, thiserror::Error)]
pub enum OutputRefused {
    /// The output is one of the inputs (or the running script).
    #[error("{what} {}: is the same file as {input} {}; an output never replaces an input", path.display(), input_path.display())]
    IsInput {
        /// The flag or step that names the output.
        what: String,
        /// The output's path as given.
        path: PathBuf,
        /// The flag, argument or step that names the input.
        input: String,
        /// The input's path as given.
        input_path: PathBuf,
    },
    /// The output's extension is not one of its kind's.
    #[error("{what} {}: {} is written as .{}", path.display(), kind.name(), kind.extensions().join(", ."))]
    Extension {
        /// The flag or step.
        what: String,
        /// The path as given.
        path: PathBuf,
        /// What it writes.
        kind: OutputKind,
    },
    /// Something that is not a regular file is at the path (a link, a directory, a device).
    #[error("{what} {}: refusing to replace something that is not a regular file (a link, directory, device or FIFO)", path.display())]
    NotRegularFile {
        /// The flag or step.
        what: String,
        /// The path as given.
        path: PathBuf,
    },
    /// A file of another kind, or one this program did not write, is at the path.
    #[error("{what} {}: refusing to replace a file that is not {} this program wrote", path.display(), kind.name())]
    OtherKind {
        /// The flag or step.
        what: String,
        /// The path as given.
        path: PathBuf,
        /// What the output is.
        kind: OutputKind,
    },
    /// The real path lies outside every allowed folder.
    #[error("{what} {}: its real path {} is outside {}; pass --allow-outside to write there", path.display(), real.display(), folders)]
    Outside {
        /// The flag or step.
        what: String,
        /// The path as given.
        path: PathBuf,
        /// Where it really is, links resolved.
        real: PathBuf,
        /// The allowed folders, described.
        folders: String,
    },
    /// The path could not be inspected.
    #[error("{what} {}: cannot inspect: {source}", path.display())]
    Inspect {
        /// The flag or step.
        what: String,
        /// The path as given.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
}

/// The inputs and folders one command's outputs are checked against.
#[derive(Clone, Debug, Default)]
pub struct OutputRule {
    /// (what names it, the path as given, its real path).
    inputs: Vec<(String, PathBuf, PathBuf)>,
    /// (the path as given, its real path); empty: anywhere.
    folders: Vec<(PathBuf, PathBuf)>,
}

impl OutputRule {
    /// A rule with no inputs, allowing every folder.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds an input (a file the command reads; `what` names the flag, argument or step).
    #[must_use]
    pub fn input(mut self, what: impl Into<String>, path: &Path) -> Self {
        self.inputs
            .push((what.into(), path.to_path_buf(), real_path(path)));
        self
    }

    /// Allows outputs only inside `folder` (and every other folder given this way).
    #[must_use]
    pub fn within(mut self, folder: &Path) -> Self {
        self.folders.push((folder.to_path_buf(), real_path(folder)));
        self
    }

    /// Checks the output `path` of `kind`, named by `what` (a flag or a step).
    ///
    /// # Errors
    /// The first part of the rule it breaks.
    pub fn check(&self, what: &str, path: &Path, kind: OutputKind) -> Result<(), OutputRefused> {
        let what = what.to_owned();
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        let any_extension = kind.extensions().is_empty();
        if !any_extension && !ext.is_some_and(|e| kind.extensions().contains(&e.as_str())) {
            return Err(OutputRefused::Extension {
                what,
                path: path.to_path_buf(),
                kind,
            });
        }
        let real = real_path(path);
        if let Some((input, input_path, _)) = self.inputs.iter().find(|(_, _, r)| *r == real) {
            return Err(OutputRefused::IsInput {
                what,
                path: path.to_path_buf(),
                input: input.clone(),
                input_path: input_path.clone(),
            });
        }
        if !self.folders.is_empty() && !self.folders.iter().any(|(_, f)| real.starts_with(f)) {
            let folders = self
                .folders
                .iter()
                .map(|(given, _)| given.display().to_string())
                .collect::<Vec<_>>()
                .join(" and ");
            return Err(OutputRefused::Outside {
                what,
                path: path.to_path_buf(),
                real,
                folders,
            });
        }
        let meta = match fs::symlink_metadata(path) {
            Ok(m) => m,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
            Err(source) => {
                return Err(OutputRefused::Inspect {
                    what,
                    path: path.to_path_buf(),
                    source,
                });
            }
        };
        if !meta.file_type().is_file() {
            return Err(OutputRefused::NotRegularFile {
                what,
                path: path.to_path_buf(),
            });
        }
        let mut head = Vec::with_capacity(HEAD_BYTES);
        let read =
            fs::File::open(path).and_then(|f| f.take(HEAD_BYTES as u64).read_to_end(&mut head));
        if let Err(source) = read {
            return Err(OutputRefused::Inspect {
                what,
                path: path.to_path_buf(),
                source,
            });
        }
        if !kind.wrote(&head) {
            return Err(OutputRefused::OtherKind {
                what,
                path: path.to_path_buf(),
                kind,
            });
        }
        Ok(())
    }
}

/// Where `path` really is: absolute, with `.` and `..` taken out and every link on the way
/// resolved. The deepest part that exists is resolved by the file system and the rest is
/// appended (so it holds for paths not written yet).
#[must_use]
pub fn real_path(path: &Path) -> PathBuf {
    let absolute = if path.is_absolute() {
        path.to_path_buf()
    } else {
        std::env::current_dir().unwrap_or_default().join(path)
    };
    // Walk down from the root, resolving as far as the file system knows the path.
    let mut real = PathBuf::new();
    let mut resolving = true;
    for c in absolute.components() {
        match c {
            Component::ParentDir => {
                real.pop();
            }
            Component::CurDir => {}
            other => {
                real.push(other);
                if resolving {
                    match fs::canonicalize(&real) {
                        Ok(r) => real = r,
                        Err(_) => resolving = false,
                    }
                }
            }
        }
    }
    real
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::fs::symlink;

    #[test]
    fn real_paths_see_through_dots_and_links() {
        let dir = tempfile::tempdir().unwrap();
        let d = fs::canonicalize(dir.path()).unwrap();
        fs::create_dir(d.join("a")).unwrap();
        symlink(d.join("a"), d.join("link")).unwrap();
        assert_eq!(real_path(&d.join("link/x.ply")), d.join("a/x.ply"));
        assert_eq!(real_path(&d.join("a/../a/./y/z.ply")), d.join("a/y/z.ply"));
        assert_eq!(real_path(&d.join("missing/../a")), d.join("a"));
    }

    #[test]
    fn an_output_never_replaces_an_input_another_kind_or_a_link() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let cloud = d.join("in.ply");
        fs::write(
            &cloud,
            "ply\nformat ascii 1.0\nelement vertex 0\nend_header\n",
        )
        .unwrap();
        let rule = OutputRule::new().input("INPUT", &cloud).within(d);
        // The input, also by another spelling.
        for same in [cloud.clone(), d.join("./sub/../in.ply")] {
            let err = rule.check("--mesh", &same, OutputKind::Mesh).unwrap_err();
            assert!(matches!(err, OutputRefused::IsInput { .. }), "{err}");
            assert!(err.to_string().contains("--mesh") && err.to_string().contains("INPUT"));
        }
        // Another kind's extension, and a file of the right extension this program did not
        // write.
        let notes = d.join("notes.txt");
        fs::write(&notes, "precious").unwrap();
        assert!(matches!(
            rule.check("out", &notes, OutputKind::Particles),
            Err(OutputRefused::Extension { .. })
        ));
        let theirs = d.join("theirs.ply");
        fs::write(&theirs, "ply\nformat ascii 1.0\ncomment a scanner\n").unwrap();
        let err = rule
            .check("--out", &theirs, OutputKind::PointSet)
            .unwrap_err();
        assert!(matches!(err, OutputRefused::OtherKind { .. }), "{err}");
        // A mesh this program wrote may not be replaced by a point set, but by a mesh.
        let mesh = d.join("m.ply");
        fs::write(
            &mesh,
            "ply\nformat binary_little_endian 1.0\ncomment dynaclay mesh\n",
        )
        .unwrap();
        assert!(rule.check("--mesh", &mesh, OutputKind::Mesh).is_ok());
        assert!(rule.check("--out", &mesh, OutputKind::PointSet).is_err());
        // Absent files are fine; a link is never replaced.
        assert!(
            rule.check("--out", &d.join("new.ply"), OutputKind::PointSet)
                .is_ok()
        );
        symlink(&mesh, d.join("link.ply")).unwrap();
        assert!(matches!(
            rule.check("--mesh", &d.join("link.ply"), OutputKind::Mesh),
            Err(OutputRefused::NotRegularFile { .. })
        ));
    }

    #[test]
    fn a_link_to_a_folder_outside_does_not_open_the_folder() {
        let inside = tempfile::tempdir().unwrap();
        let outside = tempfile::tempdir().unwrap();
        symlink(outside.path(), inside.path().join("away")).unwrap();
        let rule = OutputRule::new().within(inside.path());
        let err = rule
            .check(
                "save",
                &inside.path().join("away/s.dclay"),
                OutputKind::Session,
            )
            .unwrap_err();
        assert!(matches!(err, OutputRefused::Outside { .. }), "{err}");
        assert!(err.to_string().contains("--allow-outside"), "{err}");
        assert!(
            rule.check(
                "save",
                &inside.path().join("here/s.dclay"),
                OutputKind::Session
            )
            .is_ok()
        );
    }
}
