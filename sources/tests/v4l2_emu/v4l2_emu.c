/*
 * An emulated V4L2 camera for tests: a preloaded shim (LD_PRELOAD) that makes /dev/videoN
 * exist and answers the calls nokhwa 0.10 -> v4l 0.14 make, serving frames decoded from real
 * footage beforehand (raw YUYV files, MJPEG as numbered JPEG files).
 *
 * What the real code path calls (read from nokhwa-bindings-linux 0.1.4 and v4l 0.14):
 *   listing   opendir/readdir64("/dev") for "video*" names; open64 of
 *             /sys/class/video4linux/videoN/name (std::fs::read_to_string)
 *   opening   open("/dev/videoN", O_RDWR|O_NONBLOCK) (libc::open); close
 *   ioctls    through syscall(SYS_ioctl, ...), not ioctl(): QUERYCAP, ENUM_FMT,
 *             ENUM_FRAMESIZES, ENUM_FRAMEINTERVALS, G_FMT, S_FMT, G_PARM, S_PARM, REQBUFS,
 *             QUERYBUF, QBUF, DQBUF, STREAMON, STREAMOFF (controls only when asked: not here,
 *             so unknown requests answer ENOTTY as a driver without them does)
 *   buffers   mmap/munmap of each buffer at QUERYBUF's offset
 *   waiting   poll(fd, POLLIN, timeout) before each DQBUF (never select/epoll)
 * Both ioctl() and syscall(SYS_ioctl) are answered; everything else is passed through.
 *
 * Configuration: RIGCAST_V4L2_EMU names a text file of lines
 *   device INDEX STATE_DIR NAME...      a camera /dev/videoINDEX
 *   mode FOURCC WIDTH HEIGHT FPS PATH   a mode of the last device (YUYV: raw frames file;
 *                                       MJPG: folder of 00001.jpg, 00002.jpg, ...)
 * STATE_DIR/unplugged existing means the camera is unplugged: it leaves /dev, open fails with
 * ENOENT, calls on open descriptors fail with ENODEV and poll reports POLLERR|POLLHUP, as
 * uvcvideo does. Streaming buffers hold an flock on STATE_DIR/busy.lock, so a second
 * process (or descriptor) gets EBUSY from REQBUFS / S_FMT while one streams.
 *
 * Timing: STREAMON starts a frame clock; frame k is due at start + k/fps and, if a buffer is
 * queued, is filled with footage frame k (mod the clip's length) and stamped with its due time
 * (CLOCK_MONOTONIC, V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC). With no buffer queued the frame is
 * dropped, so a slow reader sees old frames, as with a real driver. RIGCAST_V4L2_EMU_LOG=1
 * traces every call to standard error.
 */
#define _GNU_SOURCE
#include <dirent.h>
#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/eventfd.h>
#include <sys/file.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>

#define MAX_DEVICES 8
#define MAX_MODES 32
#define MAX_FDS 4096
#define MAX_BUFS 8
#define MAX_FRAMES 4096
#define MAX_DIRS 16

struct clip {
    char path[512];
    int loaded;
    int count;
    size_t *sizes;
    const uint8_t **data;
};

struct mode {
    uint32_t fourcc, width, height, fps;
    struct clip *clip;
};

struct device {
    int index;
    char state_dir[512];
    char name[32];
    struct mode modes[MAX_MODES];
    int nmodes;
    int cur; /* current mode (format, size and rate) */
};

struct buf {
    void *addr;
    uint32_t length, offset;
    int state; /* 0 with the application, 1 queued, 2 done */
    uint64_t order;
    uint32_t seq, bytesused;
    struct timespec ts;
};

struct fh {
    struct device *dev;
    int lock_fd;
    int nbufs;
    struct buf bufs[MAX_BUFS];
    int streaming;
    struct timespec start;
    uint64_t next_seq, order;
};

static pthread_mutex_t lock = PTHREAD_MUTEX_INITIALIZER;
static struct device devices[MAX_DEVICES];
static int ndevices = -1;
static struct fh *fds[MAX_FDS];
static struct {
    DIR *dir;
    int next;
    struct dirent64 ent;
} dirs[MAX_DIRS];
static struct clip clips[MAX_MODES * MAX_DEVICES];
static int nclips;
static int logging;

#define REAL(ret, name, ...)                                                   \
    static ret (*real_##name)(__VA_ARGS__);                                    \
    if (!real_##name) real_##name = dlsym(RTLD_NEXT, #name)

static void trace(const char *fmt, ...) {
    if (!logging) return;
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "v4l2-emu: ");
    vfprintf(stderr, fmt, ap);
    fprintf(stderr, "\n");
    va_end(ap);
}

static int real_open_path(const char *path, int flags) {
    REAL(int, open, const char *, int, ...);
    return real_open(path, flags, 0);
}

/* The shim's own descriptors are closed past the interposed close(), which takes the lock. */
static int close_own(int fd) {
    REAL(int, close, int);
    return real_close(fd);
}

static void read_config(void) {
    ndevices = 0;
    logging = getenv("RIGCAST_V4L2_EMU_LOG") != NULL;
    const char *path = getenv("RIGCAST_V4L2_EMU");
    if (!path) return;
    FILE *f = fopen(path, "r");
    if (!f) return;
    char line[1024];
    while (fgets(line, sizeof line, f)) {
        char a[600], b[600];
        int index;
        unsigned w, h, fps;
        if (sscanf(line, "device %d %511s %511[^\n]", &index, a, b) == 3 &&
            ndevices < MAX_DEVICES) {
            struct device *d = &devices[ndevices++];
            memset(d, 0, sizeof *d);
            d->index = index;
            snprintf(d->state_dir, sizeof d->state_dir, "%s", a);
            snprintf(d->name, sizeof d->name, "%s", b);
        } else if (sscanf(line, "mode %4s %u %u %u %511s", a, &w, &h, &fps, b) == 5 &&
                   ndevices > 0 && fps > 0) {
            struct device *d = &devices[ndevices - 1];
            if (d->nmodes >= MAX_MODES) continue;
            struct clip *c = NULL;
            for (int i = 0; i < nclips; i++)
                if (!strcmp(clips[i].path, b)) c = &clips[i];
            if (!c && nclips < (int)(sizeof clips / sizeof clips[0])) {
                c = &clips[nclips++];
                snprintf(c->path, sizeof c->path, "%s", b);
            }
            if (!c) continue;
            struct mode *m = &d->modes[d->nmodes++];
            m->fourcc = v4l2_fourcc(a[0], a[1], a[2], a[3]);
            m->width = w;
            m->height = h;
            m->fps = fps;
            m->clip = c;
        }
    }
    fclose(f);
}

static pthread_once_t config_once = PTHREAD_ONCE_INIT;

static void load_config(void) { pthread_once(&config_once, read_config); }

static int unplugged(const struct device *d) {
    char p[600];
    struct stat st;
    snprintf(p, sizeof p, "%s/unplugged", d->state_dir);
    return stat(p, &st) == 0;
}

static struct device *device_of_path(const char *path, int *is_name) {
    int index;
    char rest[8];
    *is_name = 0;
    load_config();
    if (sscanf(path, "/dev/video%d%1s", &index, rest) == 1) {
    } else if (sscanf(path, "/sys/class/video4linux/video%d/nam%1s", &index, rest) == 2 &&
               !strcmp(rest, "e")) {
        *is_name = 1;
    } else {
        return NULL;
    }
    for (int i = 0; i < ndevices; i++)
        if (devices[i].index == index) return &devices[i];
    return NULL;
}

static uint32_t frame_size(const struct mode *m) {
    return m->width * m->height * 2; /* YUYV exactly; MJPEG at most */
}

/* Reads a whole file into memory (the MJPEG frames). */
static uint8_t *slurp(const char *path, size_t *size) {
    int fd = real_open_path(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0) return NULL;
    struct stat st;
    uint8_t *data = NULL;
    if (fstat(fd, &st) == 0 && st.st_size > 0 && (data = malloc(st.st_size))) {
        size_t got = 0;
        while (got < (size_t)st.st_size) {
            ssize_t n = read(fd, data + got, st.st_size - got);
            if (n <= 0) break;
            got += n;
        }
        *size = got;
    }
    close_own(fd);
    return data;
}

static void load_clip(struct mode *m) {
    struct clip *c = m->clip;
    if (c->loaded) return;
    c->loaded = 1;
    c->sizes = calloc(MAX_FRAMES, sizeof *c->sizes);
    c->data = calloc(MAX_FRAMES, sizeof *c->data);
    if (m->fourcc == V4L2_PIX_FMT_MJPEG) {
        for (int i = 0; i < MAX_FRAMES; i++) {
            char p[600];
            snprintf(p, sizeof p, "%s/%05d.jpg", c->path, i + 1);
            size_t n = 0;
            uint8_t *d = slurp(p, &n);
            if (!d) break;
            c->data[i] = d;
            c->sizes[i] = n;
            c->count = i + 1;
        }
    } else {
        size_t n = 0;
        uint8_t *d = slurp(c->path, &n);
        uint32_t fs = frame_size(m);
        for (size_t i = 0; d && fs && i < n / fs && i < MAX_FRAMES; i++) {
            c->data[i] = d + i * fs;
            c->sizes[i] = fs;
            c->count = (int)i + 1;
        }
    }
    trace("clip %s: %d frames", c->path, c->count);
}

static int64_t ns_of(struct timespec t) { return (int64_t)t.tv_sec * 1000000000 + t.tv_nsec; }

static struct timespec ts_of(int64_t ns) {
    struct timespec t = {ns / 1000000000, ns % 1000000000};
    return t;
}

static int64_t now_ns(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return ns_of(t);
}

/* Fills queued buffers with every frame due by now, dropping frames that find none. */
static void advance(struct fh *h) {
    if (!h->streaming) return;
    struct mode *m = &h->dev->modes[h->dev->cur];
    int64_t interval = 1000000000LL / m->fps;
    int64_t elapsed = now_ns() - ns_of(h->start);
    uint64_t due = (uint64_t)(elapsed / interval) + 1;
    if (due > h->next_seq + 1000) h->next_seq = due - MAX_BUFS;
    for (; h->next_seq < due; h->next_seq++) {
        struct buf *b = NULL;
        for (int i = 0; i < h->nbufs; i++)
            if (h->bufs[i].state == 1 && (!b || h->bufs[i].order < b->order)) b = &h->bufs[i];
        if (!b) continue; /* no buffer: the frame is dropped */
        struct clip *c = m->clip;
        if (c->count > 0 && b->addr) {
            int k = (int)(h->next_seq % (uint64_t)c->count);
            size_t n = c->sizes[k] < b->length ? c->sizes[k] : b->length;
            memcpy(b->addr, c->data[k], n);
            b->bytesused = (uint32_t)n;
        }
        b->seq = (uint32_t)h->next_seq;
        b->ts = ts_of(ns_of(h->start) + (int64_t)h->next_seq * interval);
        b->state = 2;
        b->order = h->order++;
    }
}

static int fail(int err) {
    errno = err;
    return -1;
}

/* The mode of `fourcc` nearest `w`x`h` (then nearest `fps`), or -1 for an unknown format. */
static int nearest_mode(struct device *d, uint32_t fourcc, uint32_t w, uint32_t h, uint32_t fps) {
    int best = -1;
    int64_t best_cost = 0;
    for (int i = 0; i < d->nmodes; i++) {
        struct mode *m = &d->modes[i];
        if (m->fourcc != fourcc) continue;
        int64_t dw = (int64_t)m->width - w, dh = (int64_t)m->height - h;
        int64_t df = (int64_t)m->fps - fps;
        int64_t cost = (dw * dw + dh * dh) * 1000 + (df < 0 ? -df : df);
        if (best < 0 || cost < best_cost) best = i, best_cost = cost;
    }
    return best;
}

/* Is `h` the streaming owner, or could it become one? Takes the cross-process lock. */
static int take_lock(struct fh *h) {
    if (h->lock_fd >= 0) return 0;
    char p[600];
    snprintf(p, sizeof p, "%s/busy.lock", h->dev->state_dir);
    int fd = real_open_path(p, O_RDWR | O_CREAT | O_CLOEXEC);
    if (fd < 0) return fail(EIO);
    if (flock(fd, LOCK_EX | LOCK_NB) != 0) {
        close_own(fd);
        return fail(EBUSY);
    }
    h->lock_fd = fd;
    return 0;
}

static void drop_lock(struct fh *h) {
    if (h->lock_fd >= 0) close_own(h->lock_fd);
    h->lock_fd = -1;
}

static void fill_pix(struct device *d, struct v4l2_pix_format *p) {
    struct mode *m = &d->modes[d->cur];
    memset(p, 0, sizeof *p);
    p->width = m->width;
    p->height = m->height;
    p->pixelformat = m->fourcc;
    p->field = V4L2_FIELD_NONE;
    p->bytesperline = m->fourcc == V4L2_PIX_FMT_YUYV ? m->width * 2 : 0;
    p->sizeimage = frame_size(m);
    p->colorspace = V4L2_COLORSPACE_SRGB;
}

static void fill_buffer(struct fh *h, int i, struct v4l2_buffer *b) {
    struct buf *x = &h->bufs[i];
    uint32_t type = b->type;
    memset(b, 0, sizeof *b);
    b->index = i;
    b->type = type;
    b->memory = V4L2_MEMORY_MMAP;
    b->length = x->length;
    b->m.offset = x->offset;
    b->bytesused = x->state == 2 ? x->bytesused : 0;
    b->field = V4L2_FIELD_NONE;
    b->sequence = x->seq;
    b->timestamp.tv_sec = x->ts.tv_sec;
    b->timestamp.tv_usec = x->ts.tv_nsec / 1000;
    b->flags = V4L2_BUF_FLAG_MAPPED | V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC |
               V4L2_BUF_FLAG_TSTAMP_SRC_SOE;
    if (x->state == 1) b->flags |= V4L2_BUF_FLAG_QUEUED;
    if (x->state == 2) b->flags |= V4L2_BUF_FLAG_DONE;
}

static int enum_ioctl(struct device *d, unsigned long req, void *arg) {
    if (req == VIDIOC_ENUM_FMT) {
        struct v4l2_fmtdesc *f = arg;
        uint32_t seen[MAX_MODES];
        int n = 0;
        for (int i = 0; i < d->nmodes; i++) {
            int dup = 0;
            for (int j = 0; j < n; j++) dup |= seen[j] == d->modes[i].fourcc;
            if (dup) continue;
            if ((uint32_t)n == f->index) {
                uint32_t index = f->index, type = f->type;
                memset(f, 0, sizeof *f);
                f->index = index;
                f->type = type;
                f->pixelformat = d->modes[i].fourcc;
                int mjpg = f->pixelformat == V4L2_PIX_FMT_MJPEG;
                f->flags = mjpg ? V4L2_FMT_FLAG_COMPRESSED : 0;
                snprintf((char *)f->description, sizeof f->description, "%s",
                         mjpg ? "Motion-JPEG" : "YUYV 4:2:2");
                return 0;
            }
            seen[n++] = d->modes[i].fourcc;
        }
        return fail(EINVAL);
    }
    if (req == VIDIOC_ENUM_FRAMESIZES) {
        struct v4l2_frmsizeenum *f = arg;
        uint32_t n = 0;
        for (int i = 0; i < d->nmodes; i++) {
            struct mode *m = &d->modes[i];
            if (m->fourcc != f->pixel_format) continue;
            int dup = 0;
            for (int j = 0; j < i; j++)
                dup |= d->modes[j].fourcc == m->fourcc && d->modes[j].width == m->width &&
                       d->modes[j].height == m->height;
            if (dup) continue;
            if (n++ == f->index) {
                f->type = V4L2_FRMSIZE_TYPE_DISCRETE;
                f->discrete.width = m->width;
                f->discrete.height = m->height;
                return 0;
            }
        }
        return fail(EINVAL);
    }
    if (req == VIDIOC_ENUM_FRAMEINTERVALS) {
        struct v4l2_frmivalenum *f = arg;
        uint32_t n = 0;
        for (int i = 0; i < d->nmodes; i++) {
            struct mode *m = &d->modes[i];
            if (m->fourcc != f->pixel_format || m->width != f->width || m->height != f->height)
                continue;
            if (n++ == f->index) {
                f->type = V4L2_FRMIVAL_TYPE_DISCRETE;
                f->discrete.numerator = 1;
                f->discrete.denominator = m->fps;
                return 0;
            }
        }
        return fail(EINVAL);
    }
    return fail(ENOTTY);
}

static int format_ioctl(struct fh *h, unsigned long req, void *arg) {
    struct device *d = h->dev;
    if (req == VIDIOC_G_FMT) {
        struct v4l2_format *f = arg;
        if (f->type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL);
        fill_pix(d, &f->fmt.pix);
        return 0;
    }
    if (req == VIDIOC_S_FMT || req == VIDIOC_TRY_FMT) {
        struct v4l2_format *f = arg;
        if (f->type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL);
        struct v4l2_pix_format *p = &f->fmt.pix;
        int i = nearest_mode(d, p->pixelformat, p->width, p->height, d->modes[d->cur].fps);
        if (i < 0) i = nearest_mode(d, d->modes[0].fourcc, p->width, p->height, 0);
        if (req == VIDIOC_S_FMT) {
            /* Changing the format needs the device: EBUSY while another descriptor streams. */
            if (take_lock(h) != 0) return -1;
            if (h->nbufs == 0) drop_lock(h);
            if (h->streaming) return fail(EBUSY);
            d->cur = i;
            fill_pix(d, p);
        } else {
            int cur = d->cur;
            d->cur = i;
            fill_pix(d, p);
            d->cur = cur;
        }
        return 0;
    }
    if (req == VIDIOC_G_PARM || req == VIDIOC_S_PARM) {
        struct v4l2_streamparm *s = arg;
        if (s->type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL);
        struct mode *m = &d->modes[d->cur];
        if (req == VIDIOC_S_PARM) {
            struct v4l2_fract t = s->parm.capture.timeperframe;
            uint32_t fps = t.numerator ? (t.denominator + t.numerator / 2) / t.numerator : m->fps;
            if (h->streaming) return fail(EBUSY);
            d->cur = nearest_mode(d, m->fourcc, m->width, m->height, fps);
            m = &d->modes[d->cur];
        }
        memset(&s->parm, 0, sizeof s->parm);
        s->parm.capture.capability = V4L2_CAP_TIMEPERFRAME;
        s->parm.capture.timeperframe.numerator = 1;
        s->parm.capture.timeperframe.denominator = m->fps;
        s->parm.capture.readbuffers = 0;
        return 0;
    }
    return fail(ENOTTY);
}

static int buffer_ioctl(struct fh *h, unsigned long req, void *arg) {
    struct device *d = h->dev;
    if (req == VIDIOC_REQBUFS) {
        struct v4l2_requestbuffers *r = arg;
        if (r->memory != V4L2_MEMORY_MMAP || r->type != V4L2_BUF_TYPE_VIDEO_CAPTURE)
            return fail(EINVAL);
        if (h->streaming) return fail(EBUSY);
        if (r->count == 0) {
            h->nbufs = 0;
            drop_lock(h);
            return 0;
        }
        if (take_lock(h) != 0) return -1;
        uint32_t n = r->count < 2 ? 2 : r->count > MAX_BUFS ? MAX_BUFS : r->count;
        /* As vb2 does: a buffer is sizeimage long, its mmap offset page aligned (nokhwa
         * decodes the whole mapped length, so a longer buffer would not decode as YUYV). */
        uint32_t len = frame_size(&d->modes[d->cur]);
        uint32_t stride = (len + 4095) & ~4095u;
        load_clip(&d->modes[d->cur]);
        memset(h->bufs, 0, sizeof h->bufs);
        for (uint32_t i = 0; i < n; i++) {
            h->bufs[i].length = len;
            h->bufs[i].offset = i * stride;
        }
        h->nbufs = (int)n;
        r->count = n;
        r->capabilities = V4L2_BUF_CAP_SUPPORTS_MMAP;
        return 0;
    }
    struct v4l2_buffer *b = arg;
    if (req == VIDIOC_QUERYBUF || req == VIDIOC_QBUF || req == VIDIOC_DQBUF) {
        if (b->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || b->memory != V4L2_MEMORY_MMAP)
            return fail(EINVAL);
        if (req != VIDIOC_DQBUF && (b->index >= (uint32_t)h->nbufs)) return fail(EINVAL);
    }
    if (req == VIDIOC_QUERYBUF) {
        fill_buffer(h, (int)b->index, b);
        return 0;
    }
    if (req == VIDIOC_QBUF) {
        if (h->bufs[b->index].state == 1) return fail(EINVAL);
        h->bufs[b->index].state = 1;
        h->bufs[b->index].order = h->order++;
        fill_buffer(h, (int)b->index, b);
        return 0;
    }
    if (req == VIDIOC_DQBUF) {
        if (!h->streaming) return fail(EINVAL);
        advance(h);
        int best = -1;
        for (int i = 0; i < h->nbufs; i++)
            if (h->bufs[i].state == 2 && (best < 0 || h->bufs[i].order < h->bufs[best].order))
                best = i;
        if (best < 0) return fail(EAGAIN);
        fill_buffer(h, best, b);
        h->bufs[best].state = 0;
        return 0;
    }
    if (req == VIDIOC_STREAMON) {
        if (h->nbufs == 0) return fail(EINVAL);
        if (!h->streaming) {
            clock_gettime(CLOCK_MONOTONIC, &h->start);
            h->next_seq = 0;
        }
        h->streaming = 1;
        return 0;
    }
    if (req == VIDIOC_STREAMOFF) {
        h->streaming = 0;
        for (int i = 0; i < h->nbufs; i++) h->bufs[i].state = 0;
        return 0;
    }
    return fail(ENOTTY);
}

static int emu_ioctl(struct fh *h, unsigned long req, void *arg) {
    struct device *d = h->dev;
    if (unplugged(d)) return fail(ENODEV);
    if (req == VIDIOC_QUERYCAP) {
        struct v4l2_capability *c = arg;
        memset(c, 0, sizeof *c);
        snprintf((char *)c->driver, sizeof c->driver, "rigcast-emu");
        snprintf((char *)c->card, sizeof c->card, "%s", d->name);
        snprintf((char *)c->bus_info, sizeof c->bus_info, "platform:emu-%d", d->index);
        c->version = (6 << 16) | (1 << 8);
        c->device_caps = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING;
        c->capabilities = c->device_caps | V4L2_CAP_DEVICE_CAPS;
        return 0;
    }
    if (req == VIDIOC_ENUM_FMT || req == VIDIOC_ENUM_FRAMESIZES ||
        req == VIDIOC_ENUM_FRAMEINTERVALS)
        return enum_ioctl(d, req, arg);
    if (req == VIDIOC_G_FMT || req == VIDIOC_S_FMT || req == VIDIOC_TRY_FMT ||
        req == VIDIOC_G_PARM || req == VIDIOC_S_PARM)
        return format_ioctl(h, req, arg);
    if (req == VIDIOC_REQBUFS || req == VIDIOC_QUERYBUF || req == VIDIOC_QBUF ||
        req == VIDIOC_DQBUF || req == VIDIOC_STREAMON || req == VIDIOC_STREAMOFF)
        return buffer_ioctl(h, req, arg);
    return fail(ENOTTY);
}

static struct fh *fh_of(int fd) { return fd >= 0 && fd < MAX_FDS ? fds[fd] : NULL; }

static int ioctl_common(int fd, unsigned long req, void *arg, int *handled) {
    pthread_mutex_lock(&lock);
    struct fh *h = fh_of(fd);
    int r = 0;
    *handled = h != NULL;
    if (h) {
        r = emu_ioctl(h, req, arg);
        int e = errno;
        trace("ioctl fd %d %s 0x%lx -> %d%s%s", fd, "", req, r, r ? " " : "",
              r ? strerror(e) : "");
        errno = e;
    }
    pthread_mutex_unlock(&lock);
    return r;
}

int ioctl(int fd, unsigned long req, ...) {
    va_list ap;
    va_start(ap, req);
    void *arg = va_arg(ap, void *);
    va_end(ap);
    int handled;
    int r = ioctl_common(fd, req, arg, &handled);
    if (handled) return r;
    REAL(int, ioctl, int, unsigned long, ...);
    return real_ioctl(fd, req, arg);
}

long syscall(long number, ...) {
    va_list ap;
    va_start(ap, number);
    long a[6];
    for (int i = 0; i < 6; i++) a[i] = va_arg(ap, long);
    va_end(ap);
    if (number == SYS_ioctl) {
        int handled;
        int r = ioctl_common((int)a[0], (unsigned long)a[1], (void *)a[2], &handled);
        if (handled) return r;
    }
    REAL(long, syscall, long, ...);
    return real_syscall(number, a[0], a[1], a[2], a[3], a[4], a[5]);
}

static int emu_open(const char *path, int *handled) {
    int is_name;
    struct device *d = device_of_path(path, &is_name);
    *handled = d != NULL;
    if (!d) return -1;
    pthread_mutex_lock(&lock);
    int fd = -1;
    if (unplugged(d)) {
        errno = ENOENT;
    } else if (is_name) {
        fd = memfd_create("v4l2-emu-name", MFD_CLOEXEC);
        if (fd >= 0) {
            dprintf(fd, "%s\n", d->name);
            lseek(fd, 0, SEEK_SET);
        }
    } else {
        fd = eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
        if (fd >= 0 && fd < MAX_FDS) {
            struct fh *h = calloc(1, sizeof *h);
            h->dev = d;
            h->lock_fd = -1;
            fds[fd] = h;
        }
    }
    int e = errno;
    trace("open %s -> %d", path, fd);
    pthread_mutex_unlock(&lock);
    errno = e;
    return fd;
}

#define OPEN_WRAPPER(name, ...)                                                \
    int name(__VA_ARGS__) {                                                    \
        va_list ap;                                                            \
        va_start(ap, flags);                                                   \
        mode_t mode = (flags & (O_CREAT | O_TMPFILE)) ? va_arg(ap, mode_t) : 0; \
        va_end(ap);                                                            \
        int handled;                                                           \
        int fd = emu_open(path, &handled);                                     \
        if (handled) return fd;

OPEN_WRAPPER(open, const char *path, int flags, ...)
    REAL(int, open, const char *, int, ...);
    return real_open(path, flags, mode);
}
OPEN_WRAPPER(open64, const char *path, int flags, ...)
    REAL(int, open64, const char *, int, ...);
    return real_open64(path, flags, mode);
}

/* openat and openat64: only absolute paths can name the emulated device. */
#define OPENAT_WRAPPER(name)                                                   \
    int name(int dirfd, const char *path, int flags, ...) {                    \
        va_list ap;                                                            \
        va_start(ap, flags);                                                   \
        mode_t mode = (flags & (O_CREAT | O_TMPFILE)) ? va_arg(ap, mode_t) : 0; \
        va_end(ap);                                                            \
        int handled;                                                           \
        int fd = path[0] == '/' ? emu_open(path, &handled) : (handled = 0, -1); \
        if (handled) return fd;                                                \
        REAL(int, name, int, const char *, int, ...);                          \
        return real_##name(dirfd, path, flags, mode);                          \
    }
OPENAT_WRAPPER(openat)
OPENAT_WRAPPER(openat64)

int close(int fd) {
    pthread_mutex_lock(&lock);
    struct fh *h = fh_of(fd);
    if (h) {
        drop_lock(h);
        free(h);
        fds[fd] = NULL;
        trace("close %d", fd);
    }
    pthread_mutex_unlock(&lock);
    REAL(int, close, int);
    return real_close(fd);
}

static void *emu_mmap(void *addr, size_t len, int prot, int flags, int fd, off_t off, int *handled) {
    pthread_mutex_lock(&lock);
    struct fh *h = fh_of(fd);
    void *r = MAP_FAILED;
    *handled = h != NULL;
    if (h) {
        int e = EINVAL;
        for (int i = 0; i < h->nbufs; i++) {
            if (h->bufs[i].offset != (uint32_t)off || len > h->bufs[i].length) continue;
            REAL(void *, mmap, void *, size_t, int, int, int, off_t);
            r = real_mmap(addr, len, prot, (flags & ~MAP_FIXED) | MAP_ANONYMOUS, -1, 0);
            if (r != MAP_FAILED) h->bufs[i].addr = r;
            e = errno;
        }
        if (unplugged(h->dev)) r = MAP_FAILED, e = ENODEV;
        trace("mmap fd %d offset %ld -> %p", fd, (long)off, r);
        errno = e;
    }
    pthread_mutex_unlock(&lock);
    return r;
}

void *mmap(void *addr, size_t len, int prot, int flags, int fd, off_t off) {
    int handled;
    void *r = emu_mmap(addr, len, prot, flags, fd, off, &handled);
    if (handled) return r;
    REAL(void *, mmap, void *, size_t, int, int, int, off_t);
    return real_mmap(addr, len, prot, flags, fd, off);
}

void *mmap64(void *addr, size_t len, int prot, int flags, int fd, off_t off) {
    return mmap(addr, len, prot, flags, fd, off);
}

int munmap(void *addr, size_t len) {
    pthread_mutex_lock(&lock);
    for (int fd = 0; fd < MAX_FDS; fd++) {
        if (!fds[fd]) continue;
        for (int i = 0; i < fds[fd]->nbufs; i++)
            if (fds[fd]->bufs[i].addr == addr) fds[fd]->bufs[i].addr = NULL;
    }
    pthread_mutex_unlock(&lock);
    REAL(int, munmap, void *, size_t);
    return real_munmap(addr, len);
}

/* Readiness of one emulated descriptor; 0 when nothing is ready yet. */
static short ready(struct fh *h) {
    if (unplugged(h->dev) || !h->streaming) return POLLERR | POLLHUP;
    advance(h);
    for (int i = 0; i < h->nbufs; i++)
        if (h->bufs[i].state == 2) return POLLIN | POLLRDNORM;
    return 0;
}

int poll(struct pollfd *p, nfds_t n, int timeout) {
    int any = 0;
    pthread_mutex_lock(&lock);
    for (nfds_t i = 0; i < n; i++) any |= fh_of(p[i].fd) != NULL;
    pthread_mutex_unlock(&lock);
    REAL(int, poll, struct pollfd *, nfds_t, int);
    if (!any) return real_poll(p, n, timeout);
    int64_t deadline = timeout < 0 ? INT64_MAX : now_ns() + (int64_t)timeout * 1000000;
    for (;;) {
        int count = 0;
        int64_t next_due = INT64_MAX;
        pthread_mutex_lock(&lock);
        for (nfds_t i = 0; i < n; i++) {
            struct fh *h = fh_of(p[i].fd);
            p[i].revents = h ? ready(h) & (p[i].events | POLLERR | POLLHUP) : 0;
            count += p[i].revents != 0;
            if (h && h->streaming) {
                int64_t iv = 1000000000LL / h->dev->modes[h->dev->cur].fps;
                int64_t due = ns_of(h->start) + (int64_t)h->next_seq * iv;
                if (due < next_due) next_due = due;
            }
        }
        pthread_mutex_unlock(&lock);
        int64_t now = now_ns();
        if (count || now >= deadline) return count;
        /* Sleep to the next frame, waking at least every 20 ms to notice an unplug. */
        int64_t until = next_due < deadline ? next_due : deadline;
        if (until > now + 20000000) until = now + 20000000;
        struct timespec t = ts_of(until);
        clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &t, NULL);
    }
}

DIR *opendir(const char *name) {
    REAL(DIR *, opendir, const char *);
    DIR *d = real_opendir(name);
    load_config();
    if (d && ndevices > 0 && (!strcmp(name, "/dev") || !strcmp(name, "/dev/"))) {
        pthread_mutex_lock(&lock);
        for (int i = 0; i < MAX_DIRS; i++)
            if (!dirs[i].dir) {
                dirs[i].dir = d;
                dirs[i].next = 0;
                break;
            }
        pthread_mutex_unlock(&lock);
    }
    return d;
}

/* After the real entries of /dev: one "videoN" per plugged emulated camera. */
static struct dirent64 *extra_entry(DIR *d) {
    struct dirent64 *r = NULL;
    pthread_mutex_lock(&lock);
    for (int i = 0; i < MAX_DIRS && !r; i++) {
        if (dirs[i].dir != d) continue;
        while (dirs[i].next < ndevices && !r) {
            struct device *dev = &devices[dirs[i].next++];
            if (unplugged(dev)) continue;
            memset(&dirs[i].ent, 0, sizeof dirs[i].ent);
            dirs[i].ent.d_ino = 0x7e00 + dev->index;
            dirs[i].ent.d_type = DT_CHR;
            dirs[i].ent.d_reclen = sizeof dirs[i].ent;
            snprintf(dirs[i].ent.d_name, sizeof dirs[i].ent.d_name, "video%d", dev->index);
            r = &dirs[i].ent;
        }
    }
    pthread_mutex_unlock(&lock);
    return r;
}

struct dirent64 *readdir64(DIR *d) {
    REAL(struct dirent64 *, readdir64, DIR *);
    struct dirent64 *e = real_readdir64(d);
    return e ? e : extra_entry(d);
}

struct dirent *readdir(DIR *d) {
    REAL(struct dirent *, readdir, DIR *);
    struct dirent *e = real_readdir(d);
    return e ? e : (struct dirent *)extra_entry(d);
}

int closedir(DIR *d) {
    pthread_mutex_lock(&lock);
    for (int i = 0; i < MAX_DIRS; i++)
        if (dirs[i].dir == d) dirs[i].dir = NULL;
    pthread_mutex_unlock(&lock);
    REAL(int, closedir, DIR *);
    return real_closedir(d);
}
