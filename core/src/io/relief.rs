//! Reading an image file as an emboss relief: the file is read through the size cap here, and
//! decoded by [`Relief::decode`] in the tools.

use std::path::Path;

use crate::tools::{ImageError, MAX_IMAGE_BYTES, Relief};

/// Reads a PNG or JPEG file (at most [`MAX_IMAGE_BYTES`], a regular file) as a relief of its
/// luma.
///
/// # Errors
/// An unreadable, oversized or undecodable file, naming it.
pub fn load_relief(path: &Path) -> Result<Relief, ImageError> {
    let name = path.display().to_string();
    let bytes = dynaclay_files::read_regular_file(path, MAX_IMAGE_BYTES).map_err(|source| {
        ImageError::Read {
            path: name.clone(),
            source,
        }
    })?;
    Relief::decode(&bytes, &name)
}
