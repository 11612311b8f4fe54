#pragma once
// The built-in readers, one file each; registry.cpp lists them in detection order.

#include "chronomap/ingest/registry.h"

namespace chronomap::readers {

DatasetReader tum();
DatasetReader threeDMatch();
DatasetReader scanNet();
DatasetReader dynamicMap();
DatasetReader clouds();

}  // namespace chronomap::readers
