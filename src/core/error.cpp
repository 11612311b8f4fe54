// describeError: the command line's words and exit code for an exception (core/error.h).

#include "chronomap/core/error.h"

#include "chronomap/core/memory.h"

#include <filesystem>
#include <new>

namespace chronomap {

ErrorReport describeError(const std::exception_ptr& error) {
  try {
    std::rethrow_exception(error);
  } catch (const UsageError& e) {
    return {2, e.what()};
  } catch (const Error& e) {
    return {1, e.what()};
  } catch (const std::filesystem::filesystem_error& e) {
    // The file and the system's word for the problem, not the library's own wording.
    const std::string path = e.path1().empty() ? std::string() : e.path1().string() + ": ";
    return {1, path + e.code().message()};
  } catch (const std::bad_alloc&) {
    return {1, outOfMemoryMessage()};
  } catch (const std::exception& e) {
    return {1, std::string("internal error: ") + e.what()};
  } catch (...) {
    return {1, "internal error"};
  }
}

}  // namespace chronomap
