//! IgH's `-m` / `--master`: the master indices a command works on, as a list with ranges
//! (`0`, `0,1`, `0-2`) or `-` for all of them. ecatd runs one master per daemon, index 0,
//! so the list must name index 0 only; another index belongs to another ecatd, reached with
//! `--address`.

/// Reads an IgH master index list that names only master 0, or says why not.
pub fn parse(text: &str) -> Result<u32, String> {
    let text = text.trim();
    if text == "-" {
        return Ok(0);
    }
    for part in text.split(',') {
        let (first, last) = match part.split_once('-') {
            Some((first, last)) => (index(first)?, index(last)?),
            None => (index(part)?, index(part)?),
        };
        if first > last {
            return Err(format!("{part:?} is an empty range of master indices"));
        }
        if (first, last) != (0, 0) {
            return Err(format!(
                "ecatd runs one master, index 0; {part:?} names another \
                 (each master has its own ecatd: select it with --address)"
            ));
        }
    }
    Ok(0)
}

/// One master index.
fn index(text: &str) -> Result<u32, String> {
    text.trim()
        .parse()
        .map_err(|_| format!("{text:?} is not a master index (IgH's -m: 0, 0-1, 1,4 or -)"))
}

#[cfg(test)]
mod tests {
    use super::parse;

    #[test]
    fn master_zero_in_each_of_igh_forms_is_taken() {
        for text in ["0", "-", "0-0", "0,0", " 0 "] {
            assert_eq!(parse(text), Ok(0), "{text}");
        }
    }

    #[test]
    fn another_master_or_a_bad_list_is_refused() {
        for text in ["1", "0,1", "0-1", "all", "", "1-0"] {
            assert!(parse(text).is_err(), "{text}");
        }
    }
}
