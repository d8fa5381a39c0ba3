//! The preprocessor (`preprocess`, paper §5): whole builds on scenes made in code, the cases that break a
//! naive implementation (deep trees, huge coordinates, extreme UVs, degenerate and oversize triangles),
//! the image operations, the packer and repeats wrapped in the shader.

mod alpha_atlas;
mod alpha_coverage;
mod build_tree;
mod deep_tree;
mod degenerate;
mod extreme_uvs;
mod huge_coords;
mod image_ops;
mod oversize;
mod pack;
mod palette;
mod repeat_wrap;
