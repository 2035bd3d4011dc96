//! The link receiver on arbitrary input. Nothing may panic, and:
//! 1. the bytes as a stream: every delimiter that ends a non-empty frame yields exactly one
//!    verdict — accepted or a counted error;
//! 2. the bytes as a payload (random bytes rarely survive the CRC, so the message decoders
//!    are also fed directly): an accepted message re-encodes, and re-encoding is idempotent
//!    after one round (the first normalises unused fields; bytes are compared, so NaN
//!    payloads count too);
//! 3. the bytes framed by `encode_frame`: the decoder returns exactly them.
#![no_main]

use controller_core::link::{self, Command, FrameDecoder, LinkStats, MAX_FRAME, MAX_PAYLOAD, Reply};
use libfuzzer_sys::fuzz_target;

fn check_message(payload: &[u8], stats: &mut LinkStats) {
    let mut p = [0u8; MAX_PAYLOAD];
    let mut q = [0u8; MAX_PAYLOAD];
    match (Command::decode(payload), Reply::decode(payload)) {
        (Ok(c), _) => {
            stats.frames_ok += 1;
            let n = c.encode(&mut p).expect("a decoded command re-encodes");
            let again = Command::decode(&p[..n]).expect("a re-encoded command decodes");
            let m = again.encode(&mut q).expect("re-encodes");
            assert_eq!(&p[..n], &q[..m]);
            let mut f = [0u8; MAX_FRAME];
            assert!(link::command_frame(&c, &mut f).is_ok());
        }
        (Err(_), Ok(r)) => {
            stats.frames_ok += 1;
            let n = r.encode(&mut p).expect("a decoded reply re-encodes");
            let again = Reply::decode(&p[..n]).expect("a re-encoded reply decodes");
            let m = again.encode(&mut q).expect("re-encodes");
            assert_eq!(&p[..n], &q[..m]);
        }
        (Err(e), Err(_)) => stats.count_decode(e),
    }
}

fuzz_target!(|data: &[u8]| {
    // 1. Stream.
    let mut decoder = FrameDecoder::new();
    let mut stats = LinkStats::default();
    let (mut frames, mut in_frame) = (0u32, false);
    for &b in data {
        if b == 0 {
            frames += u32::from(in_frame);
        }
        in_frame = b != 0;
        match decoder.push(b) {
            None => {}
            Some(Err(e)) => stats.count_frame(e),
            Some(Ok(p)) => {
                assert!(!p.is_empty() && p.len() <= MAX_FRAME);
                let p = p.to_vec();
                check_message(&p, &mut stats);
            }
        }
    }
    assert_eq!(stats.frames_ok + stats.errors(), frames);

    // 2. Payload.
    check_message(data, &mut LinkStats::default());

    // 3. Framed payload.
    let mut f = [0u8; MAX_FRAME];
    match link::encode_frame(data, &mut f) {
        Ok(n) => {
            let mut d = FrameDecoder::new();
            let mut got = None;
            for &b in &f[..n] {
                if let Some(r) = d.push(b) {
                    got = Some(r.map(<[u8]>::to_vec));
                }
            }
            if data.is_empty() {
                assert!(matches!(got, Some(Err(_))), "an empty payload is rejected");
            } else {
                assert_eq!(got, Some(Ok(data.to_vec())));
            }
        }
        Err(_) => assert!(data.len() > MAX_PAYLOAD),
    }
});
