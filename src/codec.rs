//! The little-endian byte codec of serialized states: fixed-width numbers,
//! length-prefixed vectors and texts, and a reader that reports truncation
//! instead of panicking.

use nalgebra::DVector;

use crate::solve::ModalState;

pub struct Writer(pub Vec<u8>);

impl Writer {
    pub fn u8(&mut self, v: u8) {
        self.0.push(v);
    }
    pub fn u32(&mut self, v: u32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    pub fn u64(&mut self, v: u64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    pub fn f64(&mut self, v: f64) {
        self.0.extend_from_slice(&v.to_bits().to_le_bytes());
    }
    pub fn opt_f64(&mut self, v: Option<f64>) {
        self.u8(v.is_some() as u8);
        self.f64(v.unwrap_or(0.0));
    }
    pub fn f64s(&mut self, v: &[f64]) {
        self.u32(v.len() as u32);
        v.iter().for_each(|x| self.f64(*x));
    }
    pub fn str(&mut self, s: &str) {
        self.u32(s.len() as u32);
        self.0.extend_from_slice(s.as_bytes());
    }
    pub fn modal(&mut self, m: &ModalState) {
        self.f64s(m.q.as_slice());
        self.f64s(m.qd.as_slice());
    }
}

pub struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    pub fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.bytes.len()).ok_or_else(|| {
            format!("serialized state truncated: need {n} bytes at offset {}, have {}", self.at, self.bytes.len())
        })?;
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }
    pub fn u8(&mut self) -> Result<u8, String> {
        Ok(self.take(1)?[0])
    }
    pub fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().expect("4 bytes")))
    }
    pub fn u64(&mut self) -> Result<u64, String> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into().expect("8 bytes")))
    }
    pub fn f64(&mut self) -> Result<f64, String> {
        Ok(f64::from_bits(self.u64()?))
    }
    pub fn opt_f64(&mut self) -> Result<Option<f64>, String> {
        let flag = self.u8()?;
        let v = self.f64()?;
        Ok(if flag != 0 { Some(v) } else { None })
    }
    pub fn f64s(&mut self, expected: usize, what: &str) -> Result<Vec<f64>, String> {
        let n = self.u32()? as usize;
        if n != expected {
            return Err(format!("serialized state has {n} {what}, this FMU has {expected}"));
        }
        (0..n).map(|_| self.f64()).collect()
    }
    pub fn str(&mut self) -> Result<String, String> {
        let n = self.u32()? as usize;
        String::from_utf8(self.take(n)?.to_vec()).map_err(|_| "serialized state: a text is not UTF-8".to_string())
    }
    pub fn modal(&mut self, n: usize) -> Result<ModalState, String> {
        Ok(ModalState {
            q: DVector::from_vec(self.f64s(n, "modal displacements")?),
            qd: DVector::from_vec(self.f64s(n, "modal velocities")?),
        })
    }
}

impl<'a> Reader<'a> {
    pub fn new(bytes: &'a [u8]) -> Self {
        Reader { bytes, at: 0 }
    }

    /// Bytes not read yet.
    pub fn remaining(&self) -> usize {
        self.bytes.len() - self.at
    }
}
