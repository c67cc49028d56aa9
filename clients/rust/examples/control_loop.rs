//! A control loop on ecatd's cycle: owns the outputs and writes the DI8's inputs (slave 2,
//! 0x6000:01..08) to the DO8's outputs (slave 1, 0x7000:01..08) every cycle, as a wired
//! test bench would echo them.
//!
//! `cargo run -p ecat-app --example control_loop -- [SOCKET] [CYCLES]`

use std::time::Duration;

use ecat_app::{App, Entry, Error};

fn main() -> Result<(), Error> {
    let mut args = std::env::args().skip(1);
    let socket = args.next().map(std::path::PathBuf::from);
    let cycles: u64 = args.next().and_then(|n| n.parse().ok()).unwrap_or(u64::MAX);
    let mut app = App::connect(socket.as_deref(), false)?;
    // Entries are looked up once; the loop itself allocates nothing.
    let pairs: Vec<(Entry, Entry)> = (1..=8)
        .map(|ch| Ok((app.entry(2, 0x6000, ch)?, app.entry(1, 0x7000, ch)?)))
        .collect::<Result<_, Error>>()?;
    app.claim()?;
    println!("owning the outputs; layout generation {}", app.generation());
    for _ in 0..cycles {
        app.wait(Duration::from_secs(1))?;
        for (input, output) in &pairs {
            let value = app.read(input);
            app.write(output, value)?;
        }
        app.commit()?;
    }
    app.release()?;
    Ok(())
}
