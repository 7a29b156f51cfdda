//! Control-stream reassembly: never panics; every decoded message passes validation.
#![no_main]

use libfuzzer_sys::fuzz_target;
use protocol::FrameDecoder;
use protocol::control::ControlError;

fuzz_target!(|data: &[u8]| {
    let mut decoder = FrameDecoder::new();
    // Feed in uneven chunks to exercise partial frames.
    for chunk in data.chunks(7) {
        decoder.push(chunk);
        loop {
            match decoder.next_message() {
                Ok(Some(message)) => assert_eq!(message.validate(), Ok(())),
                Ok(None) => break,
                Err(ControlError::FrameTooLarge { .. }) => return,
                Err(_) => {}
            }
        }
    }
});
