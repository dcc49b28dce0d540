//! Host crate for HydroBench's cross-crate integration tests (`tests/*.rs`); it has no
//! code of its own.
