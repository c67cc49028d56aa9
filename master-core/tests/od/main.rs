//! Object dictionaries and the SDO server: uploads, downloads, SDO Information, aborts, live
//! entries and a property test of the server.

#[path = "../od_support/mod.rs"]
mod od_support;

mod abort;
mod fuzz;
mod info;
mod live;
mod sdo;
