//! EoE client (spec-notes §eoe): Ethernet frames to and from a slave, IP parameters, address
//! filter.
//!
//! - [`tx`]: frames to the slave, cut into fragments for its receive mailbox, sent only
//!   when no other request waits;
//! - [`rx`]: fragments from the slave put back together (with a deadline for lost ones),
//!   published through [`SlaveMailbox::subscribe_eoe`];
//! - here: the client calls.

pub(crate) mod rx;
pub(crate) mod tx;

use std::net::Ipv4Addr;

use tokio::sync::{mpsc, oneshot};

use crate::mailbox::config::MailboxConfig;
use crate::mailbox::engine::exchange::Exchange;
use crate::mailbox::engine::hook::SideTraffic;
use crate::mailbox::engine::job::{BoxFuture, call};
use crate::mailbox::engine::slave::SlaveMailbox;
use crate::mailbox::error::{MailboxError, Result};
use crate::wire::Emit;
use crate::wire::eoe::fragment::MAX_FRAME_LEN;
use crate::wire::eoe::{AddressFilter, EoePacket, EoeRepr, EoeResult, IpParameters};
use crate::wire::mailbox::MailboxType;

use rx::EoeRx;
use tx::{EoeSend, EoeTx};

/// One slave's EoE side traffic for the engine: the bounded queue of frames to send
/// ([`MailboxConfig::eoe_tx_queue_len`]), its sender and the fragment receiver
/// ([`MailboxConfig::eoe_fragment_timeout`]).
pub(crate) fn side_traffic(config: &MailboxConfig) -> SideTraffic {
    let (queue, frames) = mpsc::channel::<EoeSend>(config.eoe_tx_queue_len.max(1));
    SideTraffic {
        queue: Box::new(queue),
        background: Box::new(EoeTx::new(frames)),
        reassembly: Box::new(EoeRx::new(config.eoe_fragment_timeout)),
    }
}

/// IP settings of an EoE slave (ETG.1000.6, spec-notes §eoe); `None` = not set / not reported.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct IpSettings {
    /// MAC address.
    pub mac: Option<[u8; 6]>,
    /// IPv4 address.
    pub ip: Option<Ipv4Addr>,
    /// Subnet mask.
    pub subnet_mask: Option<Ipv4Addr>,
    /// Default gateway.
    pub default_gateway: Option<Ipv4Addr>,
    /// DNS server.
    pub dns_server: Option<Ipv4Addr>,
    /// DNS name (ASCII, at most 32 bytes).
    pub dns_name: Option<String>,
}

impl IpSettings {
    fn to_params(&self) -> IpParameters<'_> {
        IpParameters {
            mac: self.mac,
            ip: self.ip,
            subnet_mask: self.subnet_mask,
            default_gateway: self.default_gateway,
            dns_server: self.dns_server,
            dns_name: self.dns_name.as_deref().map(str::as_bytes),
        }
    }

    fn from_params(params: &IpParameters<'_>) -> IpSettings {
        IpSettings {
            mac: params.mac,
            ip: params.ip,
            subnet_mask: params.subnet_mask,
            default_gateway: params.default_gateway,
            dns_server: params.dns_server,
            dns_name: params
                .dns_name
                .map(|name| String::from_utf8_lossy(name).into_owned()),
        }
    }
}

/// Sends one EoE request and waits for the response `accept` recognises (returning
/// `Some`); EoE answers it does not recognise are stale and skipped.
async fn eoe_request<T>(
    x: &mut Exchange,
    request: &EoeRepr<'_>,
    mut accept: impl FnMut(&EoeRepr<'_>) -> Option<Result<T>>,
) -> Result<T> {
    x.send(MailboxType::Eoe, |buf| request.emit_into(buf))
        .await?;
    loop {
        let reply = x.receive(MailboxType::Eoe).await?;
        let data = reply.data()?;
        let parsed = EoePacket::new_checked(data).and_then(|p| EoeRepr::parse(&p));
        match parsed.as_ref().ok().and_then(&mut accept) {
            Some(result) => return result,
            None => x.count_unexpected(MailboxType::Eoe),
        }
    }
}

fn check(result: EoeResult) -> Result<()> {
    if result == EoeResult::Success {
        Ok(())
    } else {
        Err(MailboxError::Eoe(result))
    }
}

impl SlaveMailbox {
    /// Sends an Ethernet frame (destination MAC first, without FCS) to the slave. Returns
    /// once every fragment is in the slave's mailbox. Frames wait in a bounded queue and go
    /// out only while no other request waits; a full queue fails at once with
    /// [`MailboxError::QueueFull`], as a network interface drops.
    pub async fn eoe_send(&self, frame: &[u8]) -> Result<()> {
        let shared = self.shared();
        let station = shared.config.station;
        if !shared.config.protocols.supports(MailboxType::Eoe) {
            return Err(MailboxError::Unsupported {
                station,
                protocol: MailboxType::Eoe,
            });
        }
        if frame.len() > MAX_FRAME_LEN {
            return Err(MailboxError::TooLarge {
                what: "EoE frame",
                size: frame.len(),
                limit: MAX_FRAME_LEN,
            });
        }
        let (done, sent) = oneshot::channel();
        let send = EoeSend {
            frame: frame.to_vec(),
            port: 0,
            done,
        };
        // The engine keeps the queue made by `side_traffic`; another type cannot be there.
        let Some(queue) = shared.side_queue.downcast_ref::<mpsc::Sender<EoeSend>>() else {
            return Err(MailboxError::Unsupported {
                station,
                protocol: MailboxType::Eoe,
            });
        };
        queue.try_send(send).map_err(|err| match err {
            tokio::sync::mpsc::error::TrySendError::Full(_) => MailboxError::QueueFull(station),
            tokio::sync::mpsc::error::TrySendError::Closed(_) => MailboxError::Shutdown,
        })?;
        sent.await.unwrap_or(Err(MailboxError::Shutdown))
    }

    /// Set IP parameter: sends the fields that are `Some` (ETG.1000.6, spec-notes §eoe).
    pub async fn eoe_set_ip(&self, settings: &IpSettings) -> Result<()> {
        let settings = settings.clone();
        call(self, Some(MailboxType::Eoe), move |x| -> BoxFuture<'_, _> {
            Box::pin(async move {
                let request = EoeRepr::SetIpRequest {
                    port: 0,
                    params: settings.to_params(),
                };
                eoe_request(x, &request, |reply| match reply {
                    EoeRepr::SetIpResponse { result, .. } => Some(check(*result)),
                    _ => None,
                })
                .await
            })
        })
        .await
    }

    /// Get IP parameter: the settings the slave reports.
    pub async fn eoe_get_ip(&self) -> Result<IpSettings> {
        call(self, Some(MailboxType::Eoe), |x| -> BoxFuture<'_, _> {
            Box::pin(async move {
                let request = EoeRepr::GetIpRequest { port: 0 };
                eoe_request(x, &request, |reply| match reply {
                    EoeRepr::GetIpResponse { result, params, .. } => {
                        Some(check(*result).map(|()| IpSettings::from_params(params)))
                    }
                    _ => None,
                })
                .await
            })
        })
        .await
    }

    /// Set address filter (spec-notes §eoe). Few slaves support it; those that do not answer
    /// [`EoeResult::NoFilterSupport`], returned as [`MailboxError::Eoe`].
    ///
    /// The fixed layout goes to a slave whose mailbox holds it; a smaller mailbox gets the
    /// packed one ([`AddressFilter::packed`]).
    pub async fn eoe_set_address_filter(&self, filter: &AddressFilter) -> Result<()> {
        let mut filter = *filter;
        call(self, Some(MailboxType::Eoe), move |x| -> BoxFuture<'_, _> {
            Box::pin(async move {
                filter.packed = x.data_capacity()
                    < crate::wire::eoe::HEADER_LEN + crate::wire::eoe::filter::FIXED_LEN;
                let request = EoeRepr::SetAddressFilterRequest { port: 0, filter };
                eoe_request(x, &request, |reply| match reply {
                    EoeRepr::SetAddressFilterResponse { result, .. } => Some(check(*result)),
                    _ => None,
                })
                .await
            })
        })
        .await
    }
}
