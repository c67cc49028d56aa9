//! CANopen over EtherCAT (mailbox type 3, digest §6).

pub mod abort;
pub mod data_type;
pub mod emergency;
pub mod header;
pub mod info;
pub mod sdo;
pub mod sdo_request;
pub mod sdo_response;
