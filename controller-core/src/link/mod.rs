//! Command/telemetry link: the frames the firmware's UART link and the processor-in-the-loop
//! link (QEMU, semihosting FIFOs) exchange, in four parts — [`framing`] (CRC, COBS, the
//! streaming receiver), [`schema`] (the messages), [`receive`] (frames to messages, counted)
//! and [`execute`](mod@execute) (what a drive does with a command).
//!
//! **Frame** on the wire: `COBS(payload ‖ CRC-16) ‖ 0x00`.
//! - `payload` = one message: a type byte, then the fields in a fixed little-endian layout
//!   (`f32`/`f64` as their IEEE-754 bits, so values cross the link bit-exactly).
//! - CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection; check value of
//!   `"123456789"` is 0x29B1) over the payload, appended little-endian.
//! - COBS (consistent overhead byte stuffing) removes every 0x00 from the frame body, so a
//!   single 0x00 delimits frames and a receiver resynchronises at the next delimiter after
//!   any corruption or lost byte.
//!
//! **Receiving**: feed bytes to a [`FrameDecoder`]; at each delimiter it yields either a
//! CRC-checked payload or a [`FrameError`], counted in [`LinkStats`]. [`Command::decode`] and
//! [`Reply::decode`] then reject unknown types, wrong lengths and invalid values with a
//! [`DecodeError`] (counted too). Nothing in this module panics for any input (fuzzed:
//! `fuzz/fuzz_targets/frame_decoder.rs`, and property-tested in `tests.rs`).
//!
//! Messages: host → drive [`Command`]s, drive → host [`Reply`]s. `Step` carries the
//! measurements of one PWM period (processor-in-the-loop only: on the board the ADC provides
//! them) and is answered by `Output`, the drive's [`FastOutput`](crate::drive::FastOutput).

pub mod execute;
pub mod framing;
pub mod receive;
pub mod schema;

pub use execute::{arm_capture, capture_reply, execute, execute_board, read_capture};
pub use framing::{
    BufferFull, FrameDecoder, FrameError, MAX_FRAME, MAX_PAYLOAD, cobs_decode_in_place, cobs_encode, crc16,
    encode_frame,
};
pub use receive::LinkStats;
pub use schema::{
    BoardCommand, BoardReadings, Command, DecodeError, LoopTiming, NackReason, RECORD_CHUNK_BYTES,
    RECORD_CHUNKS, Reply, command_frame, record_chunk, reply_frame,
};

#[cfg(test)]
mod tests;
