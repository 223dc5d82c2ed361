/* Counts C heap allocations (malloc, calloc, realloc, posix_memalign, aligned_alloc) made by
 * threads that asked to be counted, for measuring what ONNX Runtime allocates inside a model
 * run (its C++ code does not go through Rust's global allocator). Preloaded by
 * scripts/count-ort-mallocs.sh; tests/vision_alloc.rs finds the two functions below with
 * dlsym and reports the count when they are present. */
#include <stddef.h>
#include <stdatomic.h>

extern void *__libc_malloc(size_t);
extern void *__libc_calloc(size_t, size_t);
extern void *__libc_realloc(void *, size_t);
extern void *__libc_memalign(size_t, size_t);

static atomic_ulong count;
static __thread int counting;

void rigcast_malloc_counting(int on) { counting = on; }
unsigned long rigcast_malloc_count(void) { return atomic_load(&count); }

static void note(void) {
    if (counting) atomic_fetch_add(&count, 1);
}

void *malloc(size_t n) { note(); return __libc_malloc(n); }
void *calloc(size_t k, size_t n) { note(); return __libc_calloc(k, n); }
void *realloc(void *p, size_t n) { note(); return __libc_realloc(p, n); }
void *aligned_alloc(size_t a, size_t n) { note(); return __libc_memalign(a, n); }
void *memalign(size_t a, size_t n) { note(); return __libc_memalign(a, n); }
int posix_memalign(void **out, size_t a, size_t n) {
    note();
    void *p = __libc_memalign(a, n);
    if (!p) return 12; /* ENOMEM */
    *out = p;
    return 0;
}
