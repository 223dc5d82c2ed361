// The frame-time budget: the page measures the time between its own renders and trades detail
// for rate in steps that keep every character recognisable, and back when there is headroom.
//
// Why levels and not one knob: on a CPU rasteriser (SwiftShader, llvmpipe) a skinned character
// costs per vertex (bone fetches and blends in software) as much as per pixel, so lowering the
// resolution alone leaves most of the cost (see BENCHMARKS.md, issue 15). Each level therefore
// sets both a render resolution and a mesh detail (a clustered proxy of each skinned mesh,
// decimate.js), plus back-face culling and label thinning.

/** Quality levels, best first. `detail`: fraction of a skinned mesh's vertices drawn (1: the
 *  file's own mesh); `pixelRatio`: at most this many canvas pixels per CSS pixel; `cull`: draw
 *  double-sided materials front faces only (a closed body shows no back faces); `labelEvery`: place
 *  the DOM labels at every n-th render; `jointSegments`: the skeleton overlay's joint spheres'
 *  tessellation (around, top to bottom). */
export const LEVELS = [
  { name: 'full', detail: 1, pixelRatio: 2, cull: false, labelEvery: 1, jointSegments: [10, 8] },
  { name: 'balanced', detail: 0.25, pixelRatio: 0.75, cull: true, labelEvery: 2, jointSegments: [8, 5] },
  { name: 'low', detail: 0.08, pixelRatio: 0.5, cull: true, labelEvery: 4, jointSegments: [6, 3] },
];

export function levelIndex(name) {
  return LEVELS.findIndex((l) => l.name === name);
}

/**
 * Measures frame times and picks the level.
 *
 * A frame's time is measured from the display frame (requestAnimationFrame) that rendered it
 * to the next display frame: under a software rasteriser the GPU process finishes the drawing
 * after the page's render call has returned, and the browser offers the next display frame
 * only when it is done, so this interval is the whole cost of a frame, whatever its part.
 * Display frames with nothing to draw (no new pose, camera still) are not frames of the page's
 * cost and are not counted.
 *
 * Every window of ~1 s is judged on its mean frame time. Over budget: one level down. Under
 * `headroom` × budget for `upAfterWindows` windows: one level up, as a trial; a trial over
 * budget within two windows goes back down and the next trial waits twice as long (a level
 * that cannot hold the budget is not retried every few seconds, which would stutter), up to
 * `maxWaitWindows`. A forced level (`?quality=`) never changes.
 *
 * Besides the level, one pacing rule: a render waits until twice the page's own share of the
 * previous one (its JavaScript, `workMs`) has passed, which leaves the main thread at least half
 * of the time for the stream's messages, so frames never queue up into seconds of latency.
 */
export class QualityBudget {
  constructor({ budgetMs = 33, headroom = 0.6, upAfterWindows = 3, maxWaitWindows = 32, forced = null, onChange = () => {} } = {}) {
    this.budgetMs = budgetMs;
    this.headroom = headroom;
    this.upAfter = upAfterWindows;
    this.waitWindows = upAfterWindows;
    this.maxWait = maxWaitWindows;
    this.forced = forced === null || forced < 0 ? -1 : forced;
    this.level = this.forced >= 0 ? this.forced : 0;
    this.onChange = onChange;
    this.renderedAt = null; // display frame of the last render, until the next display frame
    this.lastRender = null;
    this.workMs = 0; // mean JavaScript time of a render (pacing)
    this.window = { start: null, frames: 0, renders: 0, frameMs: 0 };
    this.goodWindows = 0;
    this.trial = null; // { windows }: a step up being tried
    this.held = false; // paused: the level stays (a change would re-size the held picture)
    this.rendersPerSecond = 0;
    this.displayFramesPerSecond = 0;
    this.meanFrameMs = 0;
    this.changes = [];
  }

  get current() {
    return LEVELS[this.level];
  }

  /** At the start of every display frame: closes the previous render's frame time. */
  frame(now) {
    const w = this.window;
    if (w.start === null) w.start = now;
    w.frames++;
    if (this.renderedAt !== null) {
      w.frameMs += now - this.renderedAt;
      w.renders++;
      this.renderedAt = null;
    }
    const elapsed = now - w.start;
    if (elapsed < 1000) return;
    this.displayFramesPerSecond = (1000 * w.frames) / elapsed;
    this.rendersPerSecond = (1000 * w.renders) / elapsed;
    // A window with hardly any renders (paused, nothing moving) says nothing about the cost.
    if (w.renders >= 3) {
      this.meanFrameMs = w.frameMs / w.renders;
      if (this.forced < 0 && !this.held) this.judge(this.meanFrameMs, now);
    }
    this.window = { start: now, frames: 0, renders: 0, frameMs: 0 };
  }

  /** Holds the level while the view is paused; the window restarts either way, so frames
   *  from before a pause or a resume are never judged after it. */
  hold(on) {
    this.held = on;
    this.window = { start: null, frames: 0, renders: 0, frameMs: 0 };
    this.renderedAt = null;
  }

  /** Whether a render may start now (the pacing rule). */
  due(now) {
    return this.lastRender === null || now - this.lastRender >= 2 * this.workMs;
  }

  /** After each render: when its display frame began, and the page's JavaScript time for it. */
  rendered(frameStart, workMs) {
    this.renderedAt = frameStart;
    this.lastRender = frameStart;
    this.workMs = this.workMs === 0 ? workMs : 0.9 * this.workMs + 0.1 * workMs;
  }

  judge(intervalMs, now) {
    if (this.trial) this.trial.windows++;
    if (intervalMs > this.budgetMs) {
      this.goodWindows = 0;
      if (this.trial && this.trial.windows <= 2) {
        // The step up did not hold: back, and wait longer before the next try.
        this.waitWindows = Math.min(this.maxWait, 2 * this.waitWindows);
        this.trial = null;
      }
      if (this.level < LEVELS.length - 1) this.set(this.level + 1, now, intervalMs);
      return;
    }
    if (this.trial && this.trial.windows > 2) { this.trial = null; this.waitWindows = this.upAfter; } // it held
    if (intervalMs < this.headroom * this.budgetMs) this.goodWindows++;
    else this.goodWindows = 0;
    if (this.level > 0 && this.goodWindows >= this.waitWindows) {
      this.goodWindows = 0;
      this.trial = { windows: 0 };
      this.set(this.level - 1, now, intervalMs);
    }
  }

  set(level, now, intervalMs) {
    this.changes.push({ at: Math.round(now), from: LEVELS[this.level].name, to: LEVELS[level].name, intervalMs: Math.round(intervalMs) });
    if (this.changes.length > 20) this.changes.shift();
    this.level = level;
    this.onChange(this.current);
  }

  report() {
    return {
      quality: this.current.name,
      forced: this.forced >= 0,
      budgetMs: this.budgetMs,
      frameMs: this.meanFrameMs,
      workMs: this.workMs,
      rendersPerSecond: this.rendersPerSecond,
      displayFramesPerSecond: this.displayFramesPerSecond,
      changes: this.changes,
    };
  }
}
