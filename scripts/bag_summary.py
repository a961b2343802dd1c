#!/usr/bin/env python3
"""Prints messages per topic and their rates for a recorded session bag. Exit 1 if the bag is missing or empty."""
import sys

import rosbag


def print_per_instrument(bag, topic):
    stamps = {}
    for _, message, _ in bag.read_messages(topics=[topic]):
        stamps.setdefault(message.instrument_id, []).append(message.header.stamp.to_sec())
    for slot, times in sorted(stamps.items()):
        span = times[-1] - times[0] if len(times) > 1 else 0.0
        rate = (len(times) - 1) / span if span > 0 else 0.0
        print(f"    {'instrument ' + slot:<26} {'':<32} {len(times):>9} {rate:>9.1f}")


def main(path):
    try:
        bag = rosbag.Bag(path)
    except Exception as error:  # rosbag raises several types for missing/corrupt files
        print(f"bag_summary: cannot open {path}: {error}", file=sys.stderr)
        return 1
    with bag:
        info = bag.get_type_and_topic_info()
        total = bag.get_message_count()
        print(f"session bag: {path}")
        print(f"  duration {bag.get_end_time() - bag.get_start_time():.2f} s, {total} messages" if total else
              "  empty")
        print(f"  {'topic':<28} {'type':<32} {'messages':>9} {'rate Hz':>9}")
        for topic, meta in sorted(info.topics.items()):
            stamps = [t.to_sec() for _, _, t in bag.read_messages(topics=[topic])]
            span = stamps[-1] - stamps[0] if len(stamps) > 1 else 0.0
            rate = (len(stamps) - 1) / span if span > 0 else 0.0
            print(f"  {topic:<28} {meta.msg_type:<32} {meta.message_count:>9} {rate:>9.1f}")
            if meta.msg_type == "vrm_msgs/InstrumentState":
                print_per_instrument(bag, topic)
    return 0 if total else 1


if __name__ == "__main__":
    if len(sys.argv) != 2:
        print("usage: bag_summary.py SESSION.bag", file=sys.stderr)
        sys.exit(2)
    sys.exit(main(sys.argv[1]))
