// Live rate/latency graph: one sample per subject per 250 ms over the last 20 s.

const WINDOW_SECS = 20;

export class Graph {
  constructor(canvas) {
    this.canvas = canvas;
    this.ctx = canvas.getContext('2d');
    this.samples = []; // { t, rate, latency }
  }

  push(t, rate, latency) {
    this.samples.push({ t, rate, latency });
    while (this.samples.length && t - this.samples[0].t > WINDOW_SECS) this.samples.shift();
  }

  draw(now) {
    const { ctx, canvas } = this;
    const w = canvas.width, h = canvas.height;
    ctx.clearRect(0, 0, w, h);
    const maxRate = Math.max(60, ...this.samples.map((s) => s.rate)) * 1.1;
    const maxLatency = Math.max(20, ...this.samples.map((s) => s.latency)) * 1.1;
    ctx.strokeStyle = '#2a2e3a';
    ctx.fillStyle = '#8a90a0';
    ctx.font = '10px "DejaVu Sans", sans-serif';
    for (let i = 1; i < 4; i++) {
      const y = (h * i) / 4;
      ctx.beginPath(); ctx.moveTo(0, y); ctx.lineTo(w, y); ctx.stroke();
    }
    const line = (key, max, color) => {
      ctx.strokeStyle = color;
      ctx.lineWidth = 1.5;
      ctx.beginPath();
      this.samples.forEach((s, i) => {
        const x = w - ((now - s.t) / WINDOW_SECS) * w;
        const y = h - (s[key] / max) * (h - 4);
        if (i === 0) ctx.moveTo(x, y); else ctx.lineTo(x, y);
      });
      ctx.stroke();
    };
    line('rate', maxRate, '#4fc3f7');
    line('latency', maxLatency, '#ffb74d');
    const last = this.samples[this.samples.length - 1];
    ctx.fillStyle = '#4fc3f7';
    ctx.fillText(`${last ? last.rate.toFixed(0) : '–'} fps (max ${maxRate.toFixed(0)})`, 4, 12);
    ctx.fillStyle = '#ffb74d';
    ctx.fillText(`${last ? last.latency.toFixed(1) : '–'} ms (max ${maxLatency.toFixed(0)})`, 4, 24);
  }
}
