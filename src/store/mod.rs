//! The paging file.
