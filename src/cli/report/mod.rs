//! What the commands show people: charts ([`plot`]), percentiles ([`stats`]) and result
//! pictures ([`overlay`]).

pub mod overlay;
pub mod plot;
pub mod stats;
