//! Streaming a progressive render to a running [tev](https://github.com/Tom94/tev) image
//! viewer over its TCP protocol, as pbrt-v4's `--display-server` does.

use std::{
    net::{TcpStream, ToSocketAddrs},
    time::{Duration, Instant},
};

use tev_client::{PacketCreateImage, PacketUpdateImage, TevClient};

use crate::{error::HemiError, resources::Image};

/// How long connecting may take.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(3);

/// A connection to tev showing one image that frames update.
pub struct DisplayServer {
    tev: Option<TevClient>,
    address: String,
    name: String,
    size: (u32, u32),
    last: Option<Instant>,
    /// Least time between two updates (the last one is always sent).
    pub interval: Duration,
    /// Updates sent.
    pub updates: u64,
}

impl DisplayServer {
    /// Connects to tev at `address` (`HOST:PORT`); the image will be called `name`.
    pub fn connect(address: &str, name: &str) -> Result<Self, HemiError> {
        let fail = |why: String| HemiError::Usage(format!("--display-server {address}: {why}"));
        let addrs = address.to_socket_addrs().map_err(|e| fail(format!("cannot resolve: {e}")))?;
        let mut last_error = String::from("no address");
        for addr in addrs {
            match TcpStream::connect_timeout(&addr, CONNECT_TIMEOUT) {
                Ok(stream) => {
                    stream.set_nodelay(true).ok();
                    return Ok(DisplayServer {
                        tev: Some(TevClient::wrap(stream)),
                        address: address.to_string(),
                        name: name.replace('\0', ""),
                        size: (0, 0),
                        last: None,
                        interval: Duration::from_millis(100),
                        updates: 0,
                    });
                }
                Err(e) => last_error = e.to_string(),
            }
        }
        Err(fail(format!("cannot connect: {last_error}")))
    }

    /// Sends `image` unless one was sent less than `interval` ago (`last`: send anyway).
    /// A connection that fails is dropped with one warning; the render goes on.
    pub fn update(&mut self, image: &Image, last: bool) {
        if !last && self.last.is_some_and(|t| t.elapsed() < self.interval) {
            return;
        }
        if let Err(e) = self.send(image) {
            super::console::note(&format!("hemi: warning: display server {}: {e}; streaming stopped", self.address));
            self.tev = None;
        }
        self.last = Some(Instant::now());
    }

    fn send(&mut self, image: &Image) -> std::io::Result<()> {
        let Some(tev) = &mut self.tev else { return Ok(()) };
        let (w, h) = (image.width, image.height);
        if w == 0 || h == 0 || image.linear.len() != w as usize * h as usize {
            return Ok(());
        }
        if self.size != (w, h) {
            tev.send(PacketCreateImage {
                image_name: &self.name,
                grab_focus: self.size == (0, 0),
                width: w,
                height: h,
                channel_names: &["R", "G", "B"],
            })?;
            self.size = (w, h);
        }
        let data: Vec<f32> = image.linear.iter().flat_map(|c| c.to_array()).collect();
        tev.send(PacketUpdateImage {
            image_name: &self.name,
            grab_focus: false,
            channel_names: &["R", "G", "B"],
            channel_offsets: &[0, 1, 2],
            channel_strides: &[3, 3, 3],
            x: 0,
            y: 0,
            width: w,
            height: h,
            data: &data,
        })?;
        self.updates += 1;
        Ok(())
    }
}
