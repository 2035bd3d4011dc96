//! Framing: `COBS(payload ‖ CRC-16) ‖ 0x00` — the CRC, the byte stuffing, the streaming
//! receiver and the frame encoder. Knows nothing of what a payload means.

/// Largest payload (type byte + fields), bytes.
pub const MAX_PAYLOAD: usize = 570;
/// Largest frame on the wire, delimiter included: payload + CRC, one COBS overhead byte per
/// 254 bytes (plus one), and the 0x00.
pub const MAX_FRAME: usize = MAX_PAYLOAD + 2 + (MAX_PAYLOAD + 2) / 254 + 1 + 1;

/// CRC-16/CCITT-FALSE (the `crc` crate's CRC-16/IBM-3740: poly 0x1021, init 0xFFFF, no
/// reflection), bitwise: no 512-byte table in flash for a few hundred bytes per frame.
const CRC16: crc::Crc<u16, crc::NoTable> = crc::Crc::<u16, crc::NoTable>::new(&crc::CRC_16_IBM_3740);

/// CRC-16/CCITT-FALSE of `data`.
pub fn crc16(data: &[u8]) -> u16 {
    CRC16.checksum(data)
}

/// Why a buffer was too small for an encoded message or frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BufferFull;

/// COBS-encode `src` into `dst` (no delimiter; the `cobs` crate). Returns the encoded length.
pub fn cobs_encode(src: &[u8], dst: &mut [u8]) -> Result<usize, BufferFull> {
    cobs::try_encode(src, dst).map_err(|_| BufferFull)
}

/// COBS-decode `buf` in place (no delimiter inside; the `cobs` crate). Returns the decoded
/// length, or `None` if `buf` is not valid COBS (a code running past the end).
pub fn cobs_decode_in_place(buf: &mut [u8]) -> Option<usize> {
    cobs::decode_in_place(buf).ok()
}

/// Frame-level errors (reported at the delimiter that ends the bad frame).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameError {
    /// More bytes than [`MAX_FRAME`] before a delimiter; dropped up to the next delimiter.
    TooLong,
    /// Invalid COBS encoding.
    Cobs,
    /// Shorter than a type byte plus the CRC.
    TooShort,
    /// CRC mismatch.
    Crc,
}

/// Streaming frame receiver with a fixed buffer of [`MAX_FRAME`] bytes.
#[derive(Clone, Debug)]
pub struct FrameDecoder {
    buf: [u8; MAX_FRAME],
    len: usize,
    overflow: bool,
}

impl Default for FrameDecoder {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameDecoder {
    /// An empty receiver.
    pub const fn new() -> Self {
        Self { buf: [0; MAX_FRAME], len: 0, overflow: false }
    }

    /// Feed one byte. At a delimiter returns the frame's payload (CRC stripped) or its error;
    /// empty frames (two delimiters in a row) are skipped silently.
    pub fn push(&mut self, byte: u8) -> Option<Result<&[u8], FrameError>> {
        if byte != 0 {
            match self.buf.get_mut(self.len) {
                Some(slot) if !self.overflow => {
                    *slot = byte;
                    self.len += 1;
                }
                _ => self.overflow = true,
            }
            return None;
        }
        let (len, overflow) = (self.len, self.overflow);
        self.len = 0;
        self.overflow = false;
        if overflow {
            return Some(Err(FrameError::TooLong));
        }
        if len == 0 {
            return None;
        }
        let Some(body) = self.buf.get_mut(..len) else { return Some(Err(FrameError::TooLong)) };
        let Some(n) = cobs_decode_in_place(body) else { return Some(Err(FrameError::Cobs)) };
        let Some(decoded) = body.get(..n) else { return Some(Err(FrameError::Cobs)) };
        let Some((payload, crc)) =
            n.checked_sub(2).and_then(|k| Some((decoded.get(..k)?, decoded.get(k..)?)))
        else {
            return Some(Err(FrameError::TooShort));
        };
        if payload.is_empty() {
            return Some(Err(FrameError::TooShort));
        }
        let got = match crc {
            [lo, hi] => u16::from_le_bytes([*lo, *hi]),
            _ => return Some(Err(FrameError::TooShort)),
        };
        if got != crc16(payload) {
            return Some(Err(FrameError::Crc));
        }
        Some(Ok(payload))
    }
}

/// Encode `payload` as a complete frame (CRC, COBS, delimiter) into `out`.
pub fn encode_frame(payload: &[u8], out: &mut [u8]) -> Result<usize, BufferFull> {
    let mut raw = [0u8; MAX_PAYLOAD + 2];
    let body = raw.get_mut(..payload.len() + 2).ok_or(BufferFull)?;
    let (p, c) = body.split_at_mut(payload.len());
    p.copy_from_slice(payload);
    c.copy_from_slice(&crc16(payload).to_le_bytes());
    let n = cobs_encode(body, out)?;
    *out.get_mut(n).ok_or(BufferFull)? = 0;
    Ok(n + 1)
}
