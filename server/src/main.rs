//! `ecatd`: the EtherCAT master daemon. See the `server` library for the parts.

use std::process::ExitCode;

use clap::{CommandFactory, Parser};
use server::config::{Args, Config};
use server::exit::{CONFIGURATION, FAILURE};

fn main() -> ExitCode {
    let args = Args::parse();
    if let Some(shell) = args.completions {
        clap_complete::generate(shell, &mut Args::command(), "ecatd", &mut std::io::stdout());
        return ExitCode::SUCCESS;
    }
    if args.man {
        return match clap_mangen::Man::new(Args::command())
            .section("8")
            .render(&mut std::io::stdout())
        {
            Ok(()) => ExitCode::SUCCESS,
            Err(err) => {
                eprintln!("ecatd: man page: {err}");
                ExitCode::from(FAILURE)
            }
        };
    }
    let config = match Config::load(&args) {
        Ok(config) => config,
        Err(err) => {
            eprintln!("ecatd: {err}");
            return ExitCode::from(CONFIGURATION);
        }
    };
    if args.print_config {
        print!("{}", config.to_toml());
        return ExitCode::SUCCESS;
    }
    if args.check_config {
        // `load` checked the file, the ENI and the segment's configuration; the rest here.
        if let Err(err) = config.check() {
            eprintln!("ecatd: {err}");
            return ExitCode::from(CONFIGURATION);
        }
        for unused in &config.eni_unused {
            println!("ENI element not used: {unused}");
        }
        println!(
            "configuration good: {} slave entries, {} groups, cycle {}",
            config.slave.len(),
            config.group.len(),
            server::config::duration::show(config.bus.cycle)
        );
        return ExitCode::SUCCESS;
    }
    if let Err(err) =
        server::logging::init(config.log_format, &config.log, config.audit_log.as_deref())
    {
        eprintln!("ecatd: {err}");
        return ExitCode::from(CONFIGURATION);
    }
    let runtime = match tokio::runtime::Builder::new_multi_thread()
        .worker_threads(config.api_threads)
        .enable_all()
        .build()
    {
        Ok(runtime) => runtime,
        Err(err) => {
            eprintln!("ecatd: cannot start the runtime: {err}");
            return ExitCode::from(FAILURE);
        }
    };
    let result = runtime.block_on(server::daemon::run(config));
    // The slaves are safe and the bus is stopped by now: a task still busy (a request cut
    // at the shutdown deadline) must not hold the exit up.
    runtime.shutdown_timeout(std::time::Duration::from_millis(500));
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            tracing::error!(%err, "ecatd failed");
            eprintln!("ecatd: {err}");
            err.exit_code()
        }
    }
}
