//! Shared helpers for ecatd's end-to-end tests (network namespaces, external tools).
