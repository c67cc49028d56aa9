//! The subcommands: one gRPC call each (FoE streams), then human or JSON output.

use proto::v1 as pb;
use serde_json::{Value, json};
use server::service::value::{ValueType, decode, encode, parse_number};
use tonic::Status;

use crate::client::{Clients, connect};
use crate::{Cli, Command};

fn failed(status: Status) -> String {
    format!("{:?}: {}", status.code(), status.message())
}

fn num<T: TryFrom<u64>>(text: &str, what: &str) -> Result<T, String> {
    parse_number(text, what).map_err(|e| e.message)
}

fn typed(ty: &str) -> Result<ValueType, String> {
    ty.parse().map_err(|e: server::service::ApiError| e.message)
}

fn unhex(text: &str) -> Result<Vec<u8>, String> {
    hex::decode(text.trim()).map_err(|_| format!("{text:?} is not hex"))
}

fn state(name: &str) -> Result<pb::AlState, String> {
    Ok(
        match name.to_ascii_uppercase().replace(['-', '_'], "").as_str() {
            "INIT" => pb::AlState::Init,
            "PREOP" => pb::AlState::Preop,
            "BOOT" => pb::AlState::Boot,
            "SAFEOP" => pb::AlState::Safeop,
            "OP" => pb::AlState::Op,
            _ => return Err(format!("unknown state {name:?}")),
        },
    )
}

fn state_text(value: i32) -> &'static str {
    match pb::AlState::try_from(value) {
        Ok(pb::AlState::Init) => "INIT",
        Ok(pb::AlState::Preop) => "PREOP",
        Ok(pb::AlState::Boot) => "BOOT",
        Ok(pb::AlState::Safeop) => "SAFEOP",
        Ok(pb::AlState::Op) => "OP",
        _ => "UNKNOWN",
    }
}

fn slave_json(s: &pb::Slave) -> Value {
    let id = s.identity.unwrap_or_default();
    json!({
        "position": s.position, "station": s.station, "alias": s.alias, "name": s.name,
        "state": state_text(s.state), "al_error": s.al_error, "al_status_code": s.al_status_code,
        "al_status_text": s.al_status_text, "mailbox_protocols": s.mailbox_protocols,
        "vendor_id": id.vendor_id, "product_code": id.product_code, "revision": id.revision,
        "serial": id.serial,
    })
}

/// What a command prints: a JSON value, and its human form.
struct Out {
    json: Value,
    human: String,
}

fn out(json: Value, human: impl Into<String>) -> Out {
    Out {
        json,
        human: human.into(),
    }
}

/// Runs the command line.
pub async fn run(cli: Cli) -> Result<(), String> {
    let mut c = connect(&cli.address, cli.token.as_deref(), cli.tls_ca.as_deref()).await?;
    let result = execute(&mut c, cli.command).await?;
    if cli.json {
        println!("{}", result.json);
    } else if !result.human.is_empty() {
        println!("{}", result.human);
    }
    Ok(())
}

async fn execute(c: &mut Clients, command: Command) -> Result<Out, String> {
    Ok(match command {
        Command::Slaves => {
            let list = c
                .bus
                .list_slaves(pb::ListSlavesRequest {})
                .await
                .map_err(failed)?
                .into_inner();
            let human = list
                .slaves
                .iter()
                .map(|s| {
                    format!(
                        "{:>3}  #{:<5} {:<6} {}  {}",
                        s.position,
                        s.station,
                        state_text(s.state),
                        if s.al_error { "E" } else { "+" },
                        s.name
                    )
                })
                .collect::<Vec<_>>()
                .join("\n");
            out(
                Value::Array(list.slaves.iter().map(slave_json).collect()),
                human,
            )
        }
        Command::States { slave, state: name } => {
            let target = state(&name)? as i32;
            let slaves = match slave {
                Some(s) => vec![s],
                None => {
                    let list = c
                        .bus
                        .list_slaves(pb::ListSlavesRequest {})
                        .await
                        .map_err(failed)?;
                    list.into_inner()
                        .slaves
                        .iter()
                        .map(|s| s.position.to_string())
                        .collect()
                }
            };
            let mut done = Vec::new();
            for slave in slaves {
                let r = c
                    .bus
                    .request_state(pb::RequestStateRequest {
                        slave,
                        state: target,
                    })
                    .await
                    .map_err(failed)?
                    .into_inner();
                done.extend(r.slave.as_ref().map(slave_json));
            }
            let human = done
                .iter()
                .map(|s| format!("{} {}", s["position"], s["state"].as_str().unwrap_or("")))
                .collect::<Vec<_>>()
                .join("\n");
            out(Value::Array(done), human)
        }
        Command::Upload {
            slave,
            index,
            subindex,
            ty,
            complete,
        } => {
            let r = c
                .coe
                .upload(pb::UploadRequest {
                    slave,
                    index: num(&index, "index")?,
                    subindex: num(&subindex, "subindex")?,
                    complete_access: complete,
                    value_type: ty,
                })
                .await
                .map_err(failed)?
                .into_inner();
            out(
                json!({"data": hex::encode(&r.data), "value": r.value}),
                r.value,
            )
        }
        Command::Download {
            slave,
            index,
            subindex,
            value,
            ty,
            complete,
        } => {
            let (data, value, value_type) = if complete {
                // Complete access takes raw bytes only.
                (unhex(&value)?, String::new(), String::new())
            } else {
                (Vec::new(), value, ty)
            };
            c.coe
                .download(pb::DownloadRequest {
                    slave,
                    index: num(&index, "index")?,
                    subindex: num(&subindex, "subindex")?,
                    data,
                    complete_access: complete,
                    value,
                    value_type,
                })
                .await
                .map_err(failed)?;
            out(json!({"ok": true}), "")
        }
        Command::Sdos { slave } => {
            let list = c
                .coe
                .object_list(pb::ObjectListRequest {
                    slave: slave.clone(),
                    list: 1,
                })
                .await
                .map_err(failed)?
                .into_inner();
            let mut objects = Vec::new();
            let mut human = Vec::new();
            for index in list.indices {
                let o = c
                    .coe
                    .object_description(pb::ObjectDescriptionRequest {
                        slave: slave.clone(),
                        index,
                    })
                    .await
                    .map_err(failed)?
                    .into_inner();
                human.push(format!(
                    "SDO 0x{:04x}, \"{}\" ({}, max subindex {})",
                    o.index, o.name, o.data_type_name, o.max_subindex
                ));
                objects.push(json!({"index": o.index, "name": o.name, "data_type": o.data_type_name, "max_subindex": o.max_subindex}));
            }
            out(Value::Array(objects), human.join("\n"))
        }
        Command::SoeRead {
            slave,
            drive,
            idn,
            ty,
        } => {
            let ty = typed(&ty)?;
            let r = c
                .soe
                .read(pb::SoeReadRequest {
                    slave,
                    drive: u32::from(drive),
                    idn: num(&idn, "IDN")?,
                    elements: 0,
                })
                .await
                .map_err(failed)?
                .into_inner();
            let value = decode(ty, &r.data).map_err(|e| e.message)?;
            out(json!({"data": hex::encode(&r.data), "value": value}), value)
        }
        Command::SoeWrite {
            slave,
            drive,
            idn,
            value,
            ty,
        } => {
            let data = encode(typed(&ty)?, &value).map_err(|e| e.message)?;
            c.soe
                .write(pb::SoeWriteRequest {
                    slave,
                    drive: u32::from(drive),
                    idn: num(&idn, "IDN")?,
                    elements: 0,
                    data,
                })
                .await
                .map_err(failed)?;
            out(json!({"ok": true}), "")
        }
        Command::FoeRead {
            slave,
            name,
            output,
            password,
        } => {
            let mut stream = c
                .foe
                .read(pb::FoeReadRequest {
                    slave,
                    name,
                    password,
                })
                .await
                .map_err(failed)?
                .into_inner();
            let mut data = Vec::new();
            while let Some(chunk) = stream.message().await.map_err(failed)? {
                data.extend_from_slice(&chunk.data);
            }
            match output {
                Some(path) => {
                    std::fs::write(&path, &data).map_err(|e| format!("{}: {e}", path.display()))?;
                    out(
                        json!({"bytes": data.len()}),
                        format!("{} bytes", data.len()),
                    )
                }
                None => out(json!({"data": hex::encode(&data)}), hex::encode(&data)),
            }
        }
        Command::FoeWrite {
            slave,
            name,
            file,
            password,
        } => {
            let data = std::fs::read(&file).map_err(|e| format!("{}: {e}", file.display()))?;
            let chunks: Vec<pb::FoeWriteChunk> = data
                .chunks(64 << 10)
                .map(|piece| pb::FoeWriteChunk {
                    slave: slave.clone(),
                    name: name.clone(),
                    password,
                    data: piece.to_vec(),
                })
                .collect();
            let chunks = if chunks.is_empty() {
                vec![pb::FoeWriteChunk {
                    slave,
                    name,
                    password,
                    data: Vec::new(),
                }]
            } else {
                chunks
            };
            let r = c
                .foe
                .write(tokio_stream::iter(chunks))
                .await
                .map_err(failed)?
                .into_inner();
            out(
                json!({"written": r.written}),
                format!("{} bytes written", r.written),
            )
        }
        Command::Voe {
            slave,
            vendor_id,
            vendor_type,
            data,
        } => {
            let r = c
                .voe
                .transfer(pb::VoeRequest {
                    slave,
                    vendor_id: num(&vendor_id, "vendor id")?,
                    vendor_type: num(&vendor_type, "vendor type")?,
                    data: unhex(&data)?,
                })
                .await
                .map_err(failed)?
                .into_inner();
            out(
                json!({"vendor_id": r.vendor_id, "vendor_type": r.vendor_type, "data": hex::encode(&r.data)}),
                format!(
                    "vendor 0x{:08x} type 0x{:04x}: {}",
                    r.vendor_id,
                    r.vendor_type,
                    hex::encode(&r.data)
                ),
            )
        }
        Command::Ip {
            slave,
            ip,
            mask,
            gateway,
            dns,
            name,
            mac,
        } => {
            if ip.is_some()
                || mask.is_some()
                || gateway.is_some()
                || dns.is_some()
                || name.is_some()
                || mac.is_some()
            {
                let settings = pb::IpSettings {
                    mac: mac.unwrap_or_default(),
                    ip: ip.unwrap_or_default(),
                    subnet_mask: mask.unwrap_or_default(),
                    default_gateway: gateway.unwrap_or_default(),
                    dns_server: dns.unwrap_or_default(),
                    dns_name: name.unwrap_or_default(),
                };
                c.eoe
                    .set_ip(pb::SetIpRequest {
                        slave,
                        settings: Some(settings),
                    })
                    .await
                    .map_err(failed)?;
                out(json!({"ok": true}), "")
            } else {
                let s = c
                    .eoe
                    .get_ip(pb::GetIpRequest { slave })
                    .await
                    .map_err(failed)?
                    .into_inner();
                let json = json!({"mac": s.mac, "ip": s.ip, "subnet_mask": s.subnet_mask,
                    "default_gateway": s.default_gateway, "dns_server": s.dns_server, "dns_name": s.dns_name});
                let human = [
                    ("MAC", &s.mac),
                    ("IP", &s.ip),
                    ("mask", &s.subnet_mask),
                    ("gateway", &s.default_gateway),
                    ("DNS", &s.dns_server),
                    ("name", &s.dns_name),
                ]
                .iter()
                .filter(|(_, v)| !v.is_empty())
                .map(|(k, v)| format!("{k}: {v}"))
                .collect::<Vec<_>>()
                .join("\n");
                out(json, human)
            }
        }
        Command::Alias { slave, alias } => {
            let r = c
                .bus
                .set_alias(pb::SetAliasRequest {
                    slave,
                    alias: num(&alias, "alias")?,
                })
                .await
                .map_err(failed)?
                .into_inner();
            out(
                json!({"alias": r.alias}),
                format!("alias 0x{:04x}", r.alias),
            )
        }
        Command::RegRead {
            slave,
            address,
            length,
        } => {
            let r = c
                .bus
                .read_register(pb::ReadRegisterRequest {
                    slave,
                    address: num(&address, "address")?,
                    length: num(&length, "length")?,
                })
                .await
                .map_err(failed)?
                .into_inner();
            out(json!({"data": hex::encode(&r.data)}), hex::encode(&r.data))
        }
        Command::RegWrite {
            slave,
            address,
            data,
        } => {
            c.bus
                .write_register(pb::WriteRegisterRequest {
                    slave,
                    address: num(&address, "address")?,
                    data: unhex(&data)?,
                })
                .await
                .map_err(failed)?;
            out(json!({"ok": true}), "")
        }
        Command::SiiRead { slave, output } => {
            let r = c
                .bus
                .read_sii(pb::ReadSiiRequest { slave })
                .await
                .map_err(failed)?
                .into_inner();
            match output {
                Some(path) => {
                    std::fs::write(&path, &r.data)
                        .map_err(|e| format!("{}: {e}", path.display()))?;
                    out(
                        json!({"bytes": r.data.len()}),
                        format!("{} bytes", r.data.len()),
                    )
                }
                None => {
                    let human = r
                        .data
                        .chunks(16)
                        .enumerate()
                        .map(|(i, row)| format!("{:04x}: {}", i * 8, hex::encode(row)))
                        .collect::<Vec<_>>()
                        .join("\n");
                    out(json!({"data": hex::encode(&r.data)}), human)
                }
            }
        }
        Command::SiiWrite { slave, word, data } => {
            c.bus
                .write_sii(pb::WriteSiiRequest {
                    slave,
                    word: num(&word, "word")?,
                    data: unhex(&data)?,
                    force: false,
                })
                .await
                .map_err(failed)?;
            out(json!({"ok": true}), "")
        }
        Command::Gateway { action } => {
            let (json, human) = crate::gateway::run(c, action).await?;
            out(json, human)
        }
        Command::Eoe => crate::eoe::run(c)
            .await
            .map(|(json, human)| out(json, human))?,
    })
}
