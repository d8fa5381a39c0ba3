//! scene-info
