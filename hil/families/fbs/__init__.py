"""What hil knows about the FBs itself: named addresses, power-on defaults, codecs of its special registers."""
