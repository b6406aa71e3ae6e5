//! A compact implicit function of the sculpt: a variational RBF `I(x) = Σ λᵢ |x − cᵢ|³ + P(x)`
//! with a linear polynomial `P`, interpolating the constrained particles and inner and outer
//! points offset along the normal (Zhang et al. §5.3, eq. 9–12), with its file format and the
//! way back to a clay, and the clay held as a compact RBF while sculpting (§5.4).

mod compact;
mod export;
mod file;
mod fit;
mod mesh;
mod sculpt;

pub use compact::{CompactClay, CompactError, CompactSettings, Reinterpolation};
pub use export::{
    ClayRbf, ExportError, ExportOptions, clay_to_rbf, flatten_clay, settle_particles,
    write_particles,
};
pub use file::{
    MAGIC, MAX_CENTRES, RbfFile, RbfFileError, VERSION, decode, encode, read_rbf, write_rbf,
};
pub use fit::{Rbf, RbfError, RbfFitReport, RbfOptions, fit_surface, solve_rbf};
pub use mesh::{clay_and_rbf_meshes, clay_rbf_distance};
pub use sculpt::{RbfSculpt, RbfSculptError};
