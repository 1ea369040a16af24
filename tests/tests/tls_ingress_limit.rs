//! The per-link ingress limit of the workspace's patched zenoh-link-tls
//! (`third_party/zenoh-link-tls/src/ingress.rs`, PATCHED.md): the crate is outside the
//! workspace, so its module's unit tests (the endpoint values, the token bucket, reads
//! paced at the rate on tokio's paused clock) are compiled and run here. The router's
//! behaviour under a real flood is `tls_never_reading.rs`.

#[allow(dead_code)] // the module's API beyond what its tests call (`read`) is the link's
#[path = "../../third_party/zenoh-link-tls/src/ingress.rs"]
mod ingress;
