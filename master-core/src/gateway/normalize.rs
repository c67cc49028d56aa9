//! Tolerance of short SDO requests (spec-notes §coe.sdo-short): some sample clients send an
//! upload request of 8 bytes instead of 10 and a download with command 0x20 and a 2-byte
//! value. Our codec reads both; before such a request goes to a slave, which may be less
//! forgiving, it is written again in the standard form (an expedited initiate of 10 bytes).

use std::borrow::Cow;

use crate::wire::Emit;
use crate::wire::coe::sdo::SDO_INITIATE_LEN;
use crate::wire::coe::{CoeFrame, CoeService, SdoFrame, SdoPayload, SdoRequest};

/// The standard form of a CoE request (mailbox data): an initiate upload or an expedited
/// initiate download re-emitted in 10 bytes; anything else unchanged.
pub(crate) fn coe_request(data: &[u8]) -> Cow<'_, [u8]> {
    let is_sdo = CoeFrame::new_checked(data).is_ok_and(|f| f.service() == CoeService::SdoRequest);
    if !is_sdo || data.len() >= SDO_INITIATE_LEN && data.get(2) != Some(&0x20) {
        return Cow::Borrowed(data);
    }
    let Ok(frame) = SdoFrame::new_checked(data) else {
        return Cow::Borrowed(data);
    };
    let request = match SdoRequest::parse(&frame) {
        Ok(r @ SdoRequest::InitiateUpload { .. }) => r,
        Ok(
            r @ SdoRequest::InitiateDownload {
                payload: SdoPayload::Expedited(_),
                ..
            },
        ) => r,
        _ => return Cow::Borrowed(data),
    };
    match request.to_vec() {
        Ok(out) => Cow::Owned(out),
        Err(_) => Cow::Borrowed(data),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_seed_samples_become_standard_requests() {
        // The sample clients' upload of 0x1018:01 (spec-notes §gateway.dialect): 8 bytes of CoE data.
        let upload = [0x00, 0x20, 0x40, 0x18, 0x10, 0x01, 0x00, 0x00];
        assert_eq!(
            &coe_request(&upload)[..],
            &[0x00, 0x20, 0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0]
        );
        // Its download of 0x6040:00 = 0x0006 with command 0x20.
        let download = [0x00, 0x20, 0x20, 0x40, 0x60, 0x00, 0x06, 0x00];
        assert_eq!(
            &coe_request(&download)[..],
            &[0x00, 0x20, 0x2B, 0x40, 0x60, 0x00, 0x06, 0x00, 0, 0]
        );
    }

    #[test]
    fn standard_and_other_requests_pass_unchanged() {
        let standard = [0x00, 0x20, 0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0];
        assert!(matches!(coe_request(&standard), Cow::Borrowed(_)));
        let segment = [0x00, 0x20, 0x60, 0, 0, 0, 0, 0, 0, 0];
        assert!(matches!(coe_request(&segment), Cow::Borrowed(_)));
        let info = [0x00, 0x80, 0x01, 0x00, 0x00, 0x00, 0x01, 0x00];
        assert!(matches!(coe_request(&info), Cow::Borrowed(_)));
    }
}
