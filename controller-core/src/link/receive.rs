//! Receiving: frames decoded into messages, every frame counted in [`LinkStats`].

use super::framing::{FrameDecoder, FrameError};
use super::schema::{BoardCommand, Command, DecodeError, Reply};

/// Error counters of one link endpoint.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkStats {
    /// Frames accepted (CRC good, message decoded).
    pub frames_ok: u32,
    /// [`FrameError::TooLong`].
    pub too_long: u32,
    /// [`FrameError::Cobs`].
    pub cobs: u32,
    /// [`FrameError::TooShort`].
    pub too_short: u32,
    /// [`FrameError::Crc`].
    pub crc: u32,
    /// [`DecodeError::UnknownType`].
    pub unknown_type: u32,
    /// [`DecodeError::Length`].
    pub length: u32,
    /// [`DecodeError::Value`].
    pub value: u32,
}

impl LinkStats {
    /// Count a frame error.
    pub fn count_frame(&mut self, e: FrameError) {
        let c = match e {
            FrameError::TooLong => &mut self.too_long,
            FrameError::Cobs => &mut self.cobs,
            FrameError::TooShort => &mut self.too_short,
            FrameError::Crc => &mut self.crc,
        };
        *c = c.saturating_add(1);
    }

    /// Count a message error.
    pub fn count_decode(&mut self, e: DecodeError) {
        let c = match e {
            DecodeError::UnknownType(_) => &mut self.unknown_type,
            DecodeError::Length => &mut self.length,
            DecodeError::Value => &mut self.value,
        };
        *c = c.saturating_add(1);
    }

    /// All rejected frames.
    pub fn errors(&self) -> u32 {
        [self.too_long, self.cobs, self.too_short, self.crc, self.unknown_type, self.length, self.value]
            .iter()
            .fold(0u32, |a, &b| a.saturating_add(b))
    }
}

impl FrameDecoder {
    /// Feed one byte; at the end of a frame that is a valid command return it. Every frame
    /// is counted in `stats`: accepted, or by its error.
    pub fn push_command(&mut self, byte: u8, stats: &mut LinkStats) -> Option<Command> {
        self.push_message(byte, stats, Command::decode)
    }

    /// [`FrameDecoder::push_command`] as the board decodes ([`Command::decode_board`]).
    pub fn push_board_command(&mut self, byte: u8, stats: &mut LinkStats) -> Option<BoardCommand> {
        self.push_message(byte, stats, Command::decode_board)
    }

    /// Feed one byte; at the end of a frame that is a valid reply return it (counted as
    /// [`FrameDecoder::push_command`]).
    pub fn push_reply(&mut self, byte: u8, stats: &mut LinkStats) -> Option<Reply> {
        self.push_message(byte, stats, Reply::decode)
    }

    fn push_message<M>(
        &mut self,
        byte: u8,
        stats: &mut LinkStats,
        decode: impl FnOnce(&[u8]) -> Result<M, DecodeError>,
    ) -> Option<M> {
        match self.push(byte)? {
            Err(e) => {
                stats.count_frame(e);
                None
            }
            Ok(payload) => match decode(payload) {
                Ok(m) => {
                    stats.frames_ok = stats.frames_ok.saturating_add(1);
                    Some(m)
                }
                Err(e) => {
                    stats.count_decode(e);
                    None
                }
            },
        }
    }
}
