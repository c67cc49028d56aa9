//! `ecat.v1.BusService`: slaves, states, events, registers and SII.

use std::pin::Pin;

use proto::v1 as pb;
use proto::v1::bus_service_server::BusService;
use tokio_stream::Stream;
use tokio_stream::StreamExt;
use tokio_stream::wrappers::BroadcastStream;
use tokio_stream::wrappers::errors::BroadcastStreamRecvError;
use tonic::{Request, Response, Status};

use super::auth::admit;
use super::convert::{event, requested_state, slave};
use super::status::narrow;
use crate::input::since::parse_since;
use crate::security::Caller;
use crate::service::history::{self, EventQuery};
use crate::service::{Core, EventView, Operation, parse_name};

/// The bus service over the core.
pub struct Bus {
    /// The service layer.
    pub core: Core,
}

type Reply<T> = Result<Response<T>, Status>;

#[tonic::async_trait]
impl BusService for Bus {
    async fn get_config(&self, _: Request<pb::GetConfigRequest>) -> Reply<pb::GetConfigResponse> {
        let (toml, eni) = self.core.effective_config();
        Ok(Response::new(pb::GetConfigResponse { toml, eni }))
    }

    async fn list_slaves(
        &self,
        _: Request<pb::ListSlavesRequest>,
    ) -> Reply<pb::ListSlavesResponse> {
        let slaves = self.core.list_slaves().iter().map(slave).collect();
        Ok(Response::new(pb::ListSlavesResponse { slaves }))
    }

    async fn get_slave(&self, request: Request<pb::GetSlaveRequest>) -> Reply<pb::Slave> {
        let view = self.core.get_slave(parse_name(&request.get_ref().slave)?)?;
        Ok(Response::new(slave(&view)))
    }

    async fn request_state(
        &self,
        request: Request<pb::RequestStateRequest>,
    ) -> Reply<pb::RequestStateResponse> {
        let ticket = admit(&self.core, &request, Operation::RequestState)?;
        let r = request.get_ref();
        let state = requested_state(r.state)?;
        let view = self
            .core
            .request_state(ticket, parse_name(&r.slave)?, state)
            .await?;
        Ok(Response::new(pb::RequestStateResponse {
            slave: Some(slave(&view)),
        }))
    }

    async fn rescan(&self, request: Request<pb::RescanRequest>) -> Reply<pb::RescanResponse> {
        let ticket = admit(&self.core, &request, Operation::Rescan)?;
        let (slaves, failures) = self.core.rescan(ticket).await?;
        Ok(Response::new(pb::RescanResponse {
            slaves: slaves.iter().map(slave).collect(),
            failures,
        }))
    }

    type WatchEventsStream = Pin<Box<dyn Stream<Item = Result<pb::Event, Status>> + Send>>;

    async fn watch_events(
        &self,
        request: Request<pb::WatchEventsRequest>,
    ) -> Reply<Self::WatchEventsStream> {
        let r = request.get_ref();
        let limit = (r.limit != 0).then_some(r.limit as usize);
        let (past, live) = self.core.events_from(r.after, limit);
        let past = tokio_stream::iter(past.into_iter().map(Ok));
        let stream = past.chain(BroadcastStream::new(live)).map(|item| {
            Ok(match item {
                Ok(view) => event(&view),
                Err(BroadcastStreamRecvError::Lagged(missed)) => event(&EventView::lagged(missed)),
            })
        });
        // Ends at shutdown, so that the server's graceful stop does not wait for it.
        let stream = futures_util::StreamExt::take_until(stream, self.core.stopped());
        Ok(Response::new(Box::pin(stream)))
    }

    async fn list_events(
        &self,
        request: Request<pb::ListEventsRequest>,
    ) -> Reply<pb::ListEventsResponse> {
        let r = request.get_ref();
        let text = |s: &str| (!s.is_empty()).then(|| s.to_owned());
        let query = EventQuery {
            since: text(&r.since)
                .map(|s| parse_since(&s, std::time::SystemTime::now()))
                .transpose()?,
            kind: text(&r.kind),
            slave: text(&r.slave).map(|s| parse_name(&s)).transpose()?,
            limit: Some(if r.limit == 0 {
                history::DEFAULT_LIMIT
            } else {
                r.limit as usize
            }),
        };
        let events = self.core.event_history(query)?.iter().map(event).collect();
        Ok(Response::new(pb::ListEventsResponse { events }))
    }

    async fn read_register(
        &self,
        request: Request<pb::ReadRegisterRequest>,
    ) -> Reply<pb::ReadRegisterResponse> {
        let r = request.get_ref();
        let data = self
            .core
            .read_register(
                request.extensions().get::<Caller>(),
                parse_name(&r.slave)?,
                narrow(r.address, "address")?,
                narrow(r.length, "length")?,
            )
            .await?;
        Ok(Response::new(pb::ReadRegisterResponse { data }))
    }

    async fn write_register(
        &self,
        request: Request<pb::WriteRegisterRequest>,
    ) -> Reply<pb::WriteRegisterResponse> {
        let ticket = admit(&self.core, &request, Operation::WriteRegister)?;
        let r = request.get_ref();
        self.core
            .write_register(
                ticket,
                parse_name(&r.slave)?,
                narrow(r.address, "address")?,
                &r.data,
            )
            .await?;
        Ok(Response::new(pb::WriteRegisterResponse {}))
    }

    async fn read_sii(&self, request: Request<pb::ReadSiiRequest>) -> Reply<pb::ReadSiiResponse> {
        let data = self
            .core
            .read_sii(parse_name(&request.get_ref().slave)?)
            .await?;
        Ok(Response::new(pb::ReadSiiResponse { data }))
    }

    async fn write_sii(
        &self,
        request: Request<pb::WriteSiiRequest>,
    ) -> Reply<pb::WriteSiiResponse> {
        let ticket = admit(&self.core, &request, Operation::WriteSii)?;
        let r = request.get_ref();
        self.core
            .write_sii(
                ticket,
                parse_name(&r.slave)?,
                narrow(r.word, "word")?,
                &r.data,
                r.force,
            )
            .await?;
        Ok(Response::new(pb::WriteSiiResponse {}))
    }

    async fn set_alias(
        &self,
        request: Request<pb::SetAliasRequest>,
    ) -> Reply<pb::SetAliasResponse> {
        let ticket = admit(&self.core, &request, Operation::SetAlias)?;
        let r = request.get_ref();
        let alias = self
            .core
            .set_alias(ticket, parse_name(&r.slave)?, narrow(r.alias, "alias")?)
            .await?;
        Ok(Response::new(pb::SetAliasResponse {
            alias: u32::from(alias),
        }))
    }

    async fn get_master(&self, _: Request<pb::GetMasterRequest>) -> Reply<pb::GetMasterResponse> {
        let m = self.core.master_view();
        Ok(Response::new(pb::GetMasterResponse {
            version: m.version,
            link: m.link,
            mac: m.mac,
            cycle_period_ns: m.cycle_period_ns,
            ready: m.ready,
            slave_count: m.slave_count,
            dc_reference: m.dc_reference,
            dc_reference_time_ns: m.dc_reference_time_ns,
            frames_sent: m.frames_sent,
            frames_received: m.frames_received,
            frames_lost: m.frames_lost,
            link_errors: m.link_errors,
            redundancy: Some(super::convert::redundancy(&m.redundancy)),
        }))
    }

    async fn read_write_register(
        &self,
        request: Request<pb::ReadWriteRegisterRequest>,
    ) -> Reply<pb::ReadWriteRegisterResponse> {
        let ticket = admit(&self.core, &request, Operation::ReadWriteRegister)?;
        let r = request.get_ref();
        let data = self
            .core
            .read_write_register(
                ticket,
                parse_name(&r.slave)?,
                narrow(r.address, "address")?,
                &r.data,
            )
            .await?;
        Ok(Response::new(pb::ReadWriteRegisterResponse { data }))
    }

    async fn list_domains(
        &self,
        _: Request<pb::ListDomainsRequest>,
    ) -> Reply<pb::ListDomainsResponse> {
        let domains = self.core.domains()?.into_iter().map(domain).collect();
        Ok(Response::new(pb::ListDomainsResponse { domains }))
    }

    async fn get_log_filter(
        &self,
        _: Request<pb::GetLogFilterRequest>,
    ) -> Reply<pb::GetLogFilterResponse> {
        let filter = self.core.log_filter()?;
        Ok(Response::new(pb::GetLogFilterResponse { filter }))
    }

    async fn set_log_filter(
        &self,
        request: Request<pb::SetLogFilterRequest>,
    ) -> Reply<pb::SetLogFilterResponse> {
        let ticket = admit(&self.core, &request, Operation::SetLogFilter)?;
        let filter = self
            .core
            .set_log_filter(ticket, &request.get_ref().filter)?;
        Ok(Response::new(pb::SetLogFilterResponse { filter }))
    }

    type CaptureStream = Pin<Box<dyn Stream<Item = Result<pb::CaptureResponse, Status>> + Send>>;

    async fn capture(&self, request: Request<pb::CaptureRequest>) -> Reply<Self::CaptureStream> {
        let ticket = admit(&self.core, &request, Operation::Capture)?;
        let r = request.get_ref();
        let done = if r.rolling {
            self.core.rolling_window(ticket).await
        } else {
            self.core
                .capture(
                    ticket,
                    r.frames,
                    std::time::Duration::from_millis(u64::from(r.duration_ms)),
                )
                .await
        }?;
        let pieces: Vec<Vec<u8>> = done
            .pcapng
            .chunks(CAPTURE_CHUNK)
            .map(<[u8]>::to_vec)
            .collect();
        let last = pieces.len().saturating_sub(1);
        let (frames, dropped) = (done.frames, done.dropped);
        let chunks = pieces.into_iter().enumerate().map(move |(i, data)| {
            let counts = if i == last { (frames, dropped) } else { (0, 0) };
            Ok(pb::CaptureResponse {
                data,
                frames: counts.0,
                dropped: counts.1,
            })
        });
        Ok(Response::new(Box::pin(tokio_stream::iter(chunks))))
    }
}

fn domain(d: crate::service::domains::DomainView) -> pb::Domain {
    pb::Domain {
        index: d.index as u32,
        logical_address: d.logical,
        size: d.data.len() as u32,
        expected_wkc: u32::from(d.expected_wkc),
        last_wkc: u32::from(d.last_wkc),
        period_ns: d.period_ns,
        slaves: d.slaves.into_iter().map(u32::from).collect(),
        entries: d
            .entries
            .into_iter()
            .map(|e| pb::DomainEntry {
                position: u32::from(e.position),
                pdo_index: u32::from(e.pdo),
                index: u32::from(e.index),
                subindex: u32::from(e.subindex),
                bit_length: u32::from(e.bit_length),
                bit_offset: e.bit_offset,
                output: e.output,
                name: e.name,
            })
            .collect(),
        data: d.data,
        wrong_wkc: d.wrong_wkc,
    }
}

/// The size of one streamed piece of a capture file.
const CAPTURE_CHUNK: usize = 64 << 10;
