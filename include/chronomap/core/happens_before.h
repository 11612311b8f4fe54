#pragma once
/// @file
/// Happens-before edges for ThreadSanitizer where work passes between threads through TBB.
/// Debian's libtbb is not instrumented, so TSan cannot see how its scheduler orders tasks and
/// would report every hand-over (a frame's voxels from the casting thread to the merging one,
/// the inputs of a parallel loop from the thread that started it) as a race. Each hand-over is
/// marked: the giving side calls CHRONOMAP_HAPPENS_BEFORE(x) when done, the taking side
/// CHRONOMAP_HAPPENS_AFTER(x) before it starts, with the same address x. Outside TSan builds
/// both are nothing.

#if defined(__SANITIZE_THREAD__)
extern "C" void __tsan_acquire(void* addr);
extern "C" void __tsan_release(void* addr);
#define CHRONOMAP_HAPPENS_BEFORE(addr) __tsan_release(const_cast<void*>(static_cast<const void*>(addr)))
#define CHRONOMAP_HAPPENS_AFTER(addr) __tsan_acquire(const_cast<void*>(static_cast<const void*>(addr)))
#else
#define CHRONOMAP_HAPPENS_BEFORE(addr) static_cast<void>(addr)
#define CHRONOMAP_HAPPENS_AFTER(addr) static_cast<void>(addr)
#endif
