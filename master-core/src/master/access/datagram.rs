//! Register reads and writes addressed to one slave, each expecting that slave to answer
//! (working counter 1 for reads and writes).

use crate::bus::{BusHandle, DatagramData, DatagramRequest};

use crate::master::error::MasterError;

/// FPRD of `len` bytes at `ado` of `station`.
pub(crate) async fn fprd(
    bus: &BusHandle,
    station: u16,
    ado: u16,
    len: usize,
    what: &'static str,
) -> Result<DatagramData, MasterError> {
    let request = DatagramRequest::fprd(station, ado, len).expect_wkc(1);
    let reply = bus.submit(request).await.map_err(MasterError::bus(what))?;
    Ok(reply.data)
}

/// FPWR of `data` at `ado` of `station`.
pub(crate) async fn fpwr(
    bus: &BusHandle,
    station: u16,
    ado: u16,
    data: impl Into<DatagramData>,
    what: &'static str,
) -> Result<(), MasterError> {
    let request = DatagramRequest::fpwr(station, ado, data).expect_wkc(1);
    bus.submit(request)
        .await
        .map(drop)
        .map_err(MasterError::bus(what))
}

/// FPRW of `data` at `ado` of `station`: returns the contents from before the write
/// (working counter 3: read and written, ETG.1000.4 §5.4.3).
pub(crate) async fn fprw(
    bus: &BusHandle,
    station: u16,
    ado: u16,
    data: impl Into<DatagramData>,
    what: &'static str,
) -> Result<DatagramData, MasterError> {
    let request = DatagramRequest::fprw(station, ado, data).expect_wkc(3);
    let reply = bus.submit(request).await.map_err(MasterError::bus(what))?;
    Ok(reply.data)
}

/// APWR of `data` at `ado` of the slave at ring `position`.
pub(crate) async fn apwr(
    bus: &BusHandle,
    position: u16,
    ado: u16,
    data: impl Into<DatagramData>,
    what: &'static str,
) -> Result<(), MasterError> {
    let request = DatagramRequest::apwr(position, ado, data).expect_wkc(1);
    bus.submit(request)
        .await
        .map(drop)
        .map_err(MasterError::bus(what))
}

/// FPRD of a u16 register of `station`.
pub(crate) async fn fprd_u16(
    bus: &BusHandle,
    station: u16,
    ado: u16,
    what: &'static str,
) -> Result<u16, MasterError> {
    let data = fprd(bus, station, ado, 2, what).await?;
    // The bus returns as many bytes as were asked for; a short reply would read as 0.
    let bytes: [u8; 2] = data
        .get(..2)
        .and_then(|b| b.try_into().ok())
        .unwrap_or_default();
    Ok(u16::from_le_bytes(bytes))
}
