//! `ecat.v1.ProcessDataService`: the process image's layout (with each slave's
//! SyncManagers and PDOs), the values of the last completed cycle, a stream of changed
//! values, and forcing outputs; the same service calls and rules as REST's
//! `/api/v1/process-data` routes.

use std::pin::Pin;
use std::time::Duration;

use proto::v1 as pb;
use proto::v1::process_data_service_server::ProcessDataService;
use tokio_stream::{Stream, StreamExt};
use tonic::{Request, Response, Status};

use super::auth::admit;
use super::status::narrow;
use crate::service::pd_stream::PdChanges;
use crate::service::pdos::SlavePdosView;
use crate::service::process_data::{
    ForceView, PdEntryView, PdInput, PdValue, PdValueView, ProcessDataView,
};
use crate::service::{ApiError, Core, Operation, SlaveName, parse_name};

/// The process-data service over the core.
pub struct ProcessData {
    /// The service layer.
    pub core: Core,
}

type Reply<T> = Result<Response<T>, Status>;

/// An empty slave field names every slave.
fn slave_of(name: &str) -> Result<Option<SlaveName>, Status> {
    Ok((!name.is_empty()).then(|| parse_name(name)).transpose()?)
}

fn entry(e: &PdEntryView) -> pb::PdEntry {
    pb::PdEntry {
        slave: u32::from(e.slave),
        station: u32::from(e.station),
        pdo: u32::from(e.pdo),
        index: u32::from(e.index),
        subindex: u32::from(e.subindex),
        name: e.name.clone(),
        data_type: e.data_type.clone(),
        bit_offset: e.bit_offset,
        bit_length: u32::from(e.bit_length),
        direction: match e.direction {
            "in" => pb::PdDirection::In,
            "out" => pb::PdDirection::Out,
            _ => pb::PdDirection::Unspecified,
        } as i32,
    }
}

fn value(v: &PdValue) -> pb::PdValue {
    use pb::pd_value::Kind;
    pb::PdValue {
        kind: Some(match v {
            PdValue::Bool(b) => Kind::BoolValue(*b),
            PdValue::Int(i) => Kind::IntValue(*i),
            PdValue::Uint(u) => Kind::UintValue(*u),
            PdValue::Real(r) => Kind::RealValue(*r),
            // The service layer writes these bytes as hex for JSON; gRPC carries bytes.
            PdValue::Hex(h) => Kind::BytesValue(hex::decode(h).unwrap_or_default()),
        }),
    }
}

fn entry_value(v: &PdValueView) -> pb::PdEntryValue {
    pb::PdEntryValue {
        entry: Some(entry(&v.entry)),
        value: Some(value(&v.value)),
        raw: v.raw.clone(),
        forced_by: v.forced_by.clone().unwrap_or_default(),
    }
}

fn force(f: &ForceView) -> pb::PdForce {
    pb::PdForce {
        entry: Some(entry(&f.entry)),
        value: Some(value(&f.value)),
        forced_by: f.by.clone(),
        r#override: f.over_owner,
        since: f.since,
    }
}

fn slave_pdos(s: &SlavePdosView) -> pb::PdSlave {
    pb::PdSlave {
        slave: u32::from(s.slave),
        station: u32::from(s.station),
        sync_managers: s
            .sync_managers
            .iter()
            .map(|sm| pb::PdSyncManager {
                index: u32::from(sm.index),
                physical_address: u32::from(sm.start),
                default_size: u32::from(sm.default_size),
                control_register: u32::from(sm.control),
                enable: u32::from(sm.enable),
                length: u32::from(sm.length),
                pdos: sm
                    .pdos
                    .iter()
                    .map(|p| pb::Pdo {
                        index: u32::from(p.index),
                        name: p.name.clone(),
                        entries: p
                            .entries
                            .iter()
                            .map(|e| pb::PdoEntry {
                                index: u32::from(e.index),
                                subindex: u32::from(e.subindex),
                                bit_length: u32::from(e.bit_length),
                                name: e.name.clone(),
                            })
                            .collect(),
                    })
                    .collect(),
            })
            .collect(),
    }
}

fn read_response(view: &ProcessDataView) -> pb::ProcessDataReadResponse {
    pb::ProcessDataReadResponse {
        cycle: view.cycle,
        wkc: u32::from(view.wkc),
        expected_wkc: u32::from(view.expected_wkc),
        entries: view.values.iter().map(entry_value).collect(),
    }
}

fn watch_response(view: &ProcessDataView) -> pb::ProcessDataWatchResponse {
    pb::ProcessDataWatchResponse {
        cycle: view.cycle,
        wkc: u32::from(view.wkc),
        expected_wkc: u32::from(view.expected_wkc),
        entries: view.values.iter().map(entry_value).collect(),
    }
}

/// The value of a force request, as REST takes a JSON value: booleans as 0 and 1.
fn input(value: Option<pb::force_request::Value>) -> Result<PdInput, Status> {
    use pb::force_request::Value;
    match value {
        Some(Value::IntValue(v)) => Ok(PdInput::Int(v)),
        Some(Value::RealValue(v)) => Ok(PdInput::Real(v)),
        Some(Value::BoolValue(b)) => Ok(PdInput::Int(i64::from(b))),
        None => Err(Status::from(ApiError::invalid_field(
            "value",
            "a value is needed: int_value, real_value or bool_value",
        ))),
    }
}

#[tonic::async_trait]
impl ProcessDataService for ProcessData {
    async fn get_layout(
        &self,
        request: Request<pb::GetLayoutRequest>,
    ) -> Reply<pb::GetLayoutResponse> {
        let slave = slave_of(&request.get_ref().slave)?;
        let layout = self.core.process_data_layout(slave)?;
        let slaves = self.core.pdo_layout(slave)?;
        Ok(Response::new(pb::GetLayoutResponse {
            generation: layout.generation,
            image_len: layout.image_len as u64,
            period_ns: layout.period_ns,
            entries: layout.entries.iter().map(entry).collect(),
            slaves: slaves.iter().map(slave_pdos).collect(),
        }))
    }

    async fn read(
        &self,
        request: Request<pb::ProcessDataReadRequest>,
    ) -> Reply<pb::ProcessDataReadResponse> {
        let view = self
            .core
            .process_data(slave_of(&request.get_ref().slave)?)?;
        Ok(Response::new(read_response(&view)))
    }

    type WatchStream =
        Pin<Box<dyn Stream<Item = Result<pb::ProcessDataWatchResponse, Status>> + Send>>;

    async fn watch(
        &self,
        request: Request<pb::ProcessDataWatchRequest>,
    ) -> Reply<Self::WatchStream> {
        let r = request.into_inner();
        let requested =
            (r.interval_ms != 0).then(|| Duration::from_millis(u64::from(r.interval_ms)));
        let interval = self.core.pd_stream_interval(requested)?;
        let slave = slave_of(&r.slave)?;
        // The slave must exist now; the stream then follows it.
        self.core.process_data(slave)?;
        let ticks = tokio_stream::wrappers::IntervalStream::new({
            let mut ticks = tokio::time::interval(interval);
            // A client that reads slowly gets the newest values, not a backlog of ticks.
            ticks.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
            ticks
        });
        let core = self.core.clone();
        let mut changes = PdChanges::default();
        let stream = ticks.filter_map(move |_| {
            core.process_data(slave)
                .ok()
                .and_then(|view| changes.next(view))
                .map(|view| Ok(watch_response(&view)))
        });
        // Ends at shutdown, so that the server's graceful stop does not wait for it.
        let stream = futures_util::StreamExt::take_until(stream, self.core.stopped());
        Ok(Response::new(Box::pin(stream)))
    }

    async fn force(&self, request: Request<pb::ForceRequest>) -> Reply<pb::ForceResponse> {
        let ticket = admit(&self.core, &request, Operation::ForceOutput)?;
        let r = request.into_inner();
        let slave = parse_name(&r.slave)?;
        let index = narrow(r.index, "index")?;
        let subindex = narrow(r.subindex, "subindex")?;
        let value = input(r.value)?;
        let view = self
            .core
            .force_output(ticket, slave, index, subindex, value, r.r#override)?;
        Ok(Response::new(pb::ForceResponse {
            force: Some(force(&view)),
        }))
    }

    async fn release_force(
        &self,
        request: Request<pb::ReleaseForceRequest>,
    ) -> Reply<pb::ReleaseForceResponse> {
        let ticket = admit(&self.core, &request, Operation::ReleaseOutput)?;
        let r = request.get_ref();
        self.core.release_output(
            ticket,
            parse_name(&r.slave)?,
            narrow(r.index, "index")?,
            narrow(r.subindex, "subindex")?,
        )?;
        Ok(Response::new(pb::ReleaseForceResponse {}))
    }

    async fn list_forced(
        &self,
        _: Request<pb::ListForcedRequest>,
    ) -> Reply<pb::ListForcedResponse> {
        Ok(Response::new(pb::ListForcedResponse {
            forced: self.core.forced_outputs().iter().map(force).collect(),
        }))
    }
}
