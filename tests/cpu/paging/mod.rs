//! Paging (`paging`, paper §6): the pager's invariants, and blocks over HTTP.

mod file_source;
mod http;
mod http_paged;
mod http_server;
mod props;
mod serve_abuse;
mod serve_cli;
