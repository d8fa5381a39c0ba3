//! The per-frame cut (`select`, paper §4): exact cuts on hand-made trees, properties on random trees,
//! cuts of real built trees, and the run-time rescaling.

mod props;
mod real_tree;
mod rescale;
mod rules;
