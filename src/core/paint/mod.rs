//! How an estimate is painted: colour ramps, the posterior as heat per
//! surface sample and per mesh vertex, the arrows' colours and lengths.
//! Imports the rooms below it; the app and the Foxglove writer share it.

pub mod colours;
pub mod heat;
pub mod vertices;
