//! camplace's small HTTP/1.1 server for its two pages (the status page of `camplace serve`
//! and the review page of `camplace review --listen`): one thread whatever the clients do,
//! one request per connection, and a bound on every byte and every second a client can
//! hold. It is not a general web server: no keep-alive, no chunked bodies, no TLS.

mod head;
mod server;

pub use head::{parse_request_head, Head, Refusal, MAX_HEAD_BYTES, MAX_REQUEST_LINE};
pub use server::{reason, Limits, Request, Response, Server, TURN};

#[cfg(test)]
mod server_tests;
