#pragma once
// Error messages set from a function that calls setjmp (the PNG and JPEG decoders; internal).

#include <string>

namespace chronomap {

/// Sets `error` to `message`. A function that calls setjmp sets its messages through this (and
/// through helpers like it that build longer ones), never inlined: a string built in its own
/// frame is a local that GCC (at -O1) warns a longjmp might clobber.
[[gnu::noinline]] inline void setMessage(std::string& error, const char* message) { error = message; }

}  // namespace chronomap
