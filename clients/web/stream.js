// The rigcast stream (protocol/PROTOCOL.md): JSON control messages and binary pose frames
// over one WebSocket, with automatic reconnect.

export const FRAME_HEADER_BYTES = 60;

/** Decodes a binary pose frame; returns null (and the caller counts it) when malformed. */
export function decodeFrame(buffer) {
  if (buffer.byteLength < FRAME_HEADER_BYTES) return null;
  const view = new DataView(buffer);
  const magic = String.fromCharCode(view.getUint8(0), view.getUint8(1), view.getUint8(2), view.getUint8(3));
  if (magic !== 'RGCF' || view.getUint16(4, true) !== 1) return null;
  const numBones = view.getUint32(12, true);
  if (buffer.byteLength !== FRAME_HEADER_BYTES + 16 * numBones) return null;
  return {
    subject: view.getUint32(8, true),
    numBones,
    seq: Number(view.getBigUint64(16, true)),
    captureNanos: view.getBigUint64(24, true),
    sendNanos: view.getBigUint64(32, true),
    missedFrames: view.getUint32(40, true),
    root: [view.getFloat32(48, true), view.getFloat32(52, true), view.getFloat32(56, true)],
    rotations: new Float32Array(buffer.slice(FRAME_HEADER_BYTES)),
  };
}

export class Stream {
  constructor(url, handlers) {
    this.url = url;
    this.handlers = handlers;
    this.socket = null;
    this.badFrames = 0;
    this.connect();
  }

  connect() {
    const socket = new WebSocket(this.url);
    socket.binaryType = 'arraybuffer';
    socket.onopen = () => this.handlers.onOpen?.();
    socket.onclose = () => {
      this.handlers.onClose?.();
      setTimeout(() => this.connect(), 1000);
    };
    socket.onmessage = (event) => {
      if (typeof event.data === 'string') {
        let message;
        try { message = JSON.parse(event.data); } catch { this.badFrames++; return; }
        this.handlers.onMessage?.(message);
      } else {
        const frame = decodeFrame(event.data);
        if (frame) this.handlers.onFrame?.(frame); else this.badFrames++;
      }
    };
    this.socket = socket;
  }

  send(message) {
    if (this.socket?.readyState === WebSocket.OPEN) this.socket.send(JSON.stringify(message));
  }
}
