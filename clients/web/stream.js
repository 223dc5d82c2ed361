// The rigcast stream (protocol/PROTOCOL.md): JSON control messages and binary pose frames
// over one WebSocket, with automatic reconnect.

export const FRAME_HEADER_BYTES = 60;
export const FRAME_V2_HEADER_BYTES = 48;
// The version the viewer asks for (set_protocol) when the server offers it.
export const WANTED_PROTOCOL_VERSION = 2;

/**
 * Decodes a binary pose frame of version 1 (bone 0's translation) or 2 (the translations of
 * every bone the skeleton message marks `translated`); returns null (and the caller counts
 * it) when malformed.
 */
export function decodeFrame(buffer) {
  if (buffer.byteLength < FRAME_V2_HEADER_BYTES) return null;
  const view = new DataView(buffer);
  const magic = String.fromCharCode(view.getUint8(0), view.getUint8(1), view.getUint8(2), view.getUint8(3));
  const version = view.getUint16(4, true);
  if (magic !== 'RGCF' || (version !== 1 && version !== 2)) return null;
  const numBones = view.getUint32(12, true);
  const numTranslations = version === 2 ? view.getUint32(44, true) : 1;
  const rotationsAt = version === 2 ? FRAME_V2_HEADER_BYTES : FRAME_HEADER_BYTES;
  const translationsAt = version === 2 ? rotationsAt + 16 * numBones : 48;
  if (buffer.byteLength !== rotationsAt + 16 * numBones + (version === 2 ? 12 * numTranslations : 0)) return null;
  const translations = new Float32Array(buffer.slice(translationsAt, translationsAt + 12 * numTranslations));
  const rotations = new Float32Array(buffer.slice(rotationsAt, rotationsAt + 16 * numBones));
  if (!translations.every(Number.isFinite) || !rotations.every(Number.isFinite)) return null;
  return {
    version,
    subject: view.getUint32(8, true),
    numBones,
    seq: Number(view.getBigUint64(16, true)),
    captureNanos: view.getBigUint64(24, true),
    sendNanos: view.getBigUint64(32, true),
    missedFrames: view.getUint32(40, true),
    root: numTranslations > 0 ? [translations[0], translations[1], translations[2]] : [0, 0, 0],
    rotations,
    translations,
  };
}

export class Stream {
  constructor(url, handlers) {
    this.url = url;
    this.handlers = handlers;
    this.socket = null;
    this.badFrames = 0;
    this.decodeMs = 0;
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
        const t = performance.now();
        const frame = decodeFrame(event.data);
        this.decodeMs += performance.now() - t; // the viewer's time budget report
        if (frame) this.handlers.onFrame?.(frame); else this.badFrames++;
      }
    };
    this.socket = socket;
  }

  send(message) {
    if (this.socket?.readyState === WebSocket.OPEN) this.socket.send(JSON.stringify(message));
  }
}
