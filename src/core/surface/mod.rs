//! The arm's surface as the estimator sees it: samples drawn over the
//! candidate links with their patches and cells, the faces a neighbouring
//! link covers, and the ray picking of the posed meshes. Imports `numerics`, `geometry` and `robot`.

pub mod cover;
pub mod picking;
pub mod sampling;
