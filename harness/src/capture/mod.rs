//! Frame capture files (classic pcap, linktype Ethernet).
