//! The atlas-tree model every stage reads (paper §3, Fig. 3): the forest, its nodes, leaves, rects and
//! vertex records (`tree.rs`, re-exported here), and the per-node texture transforms that let one UV set serve every level
//! ([`transform`], docs/DESIGN.md "Precision"), and the per-triangle texel-density rule that sizes them ([`sizing`], §5.2.1).
//!
//! `preprocess` produces this model, `store` writes and reads it, and `select`, `render`, `inspect` read it;
//! none of them imports the preprocessor.

pub mod sizing;
pub mod transform;
mod tree;

pub use tree::*;
