//! The preprocessor (paper §5).

pub mod area;
pub mod image_ops;
pub mod pack;
pub mod sizing;
pub mod tree;
